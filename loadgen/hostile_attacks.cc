#include "loadgen/hostile_attacks.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <thread>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "client/client_testing.h"
#include "loadgen/loopback_room.h"
#include "loadgen/scenes/scenes.h"
#include "protocol/connection.h"
#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/packet.h"

namespace edgephys::loadgen {

Status RecordingSocket::SendTo(const Endpoint& to, std::span<const uint8_t> data) {
  if (data.size() > kPacketPrefixSize && data[5] == static_cast<uint8_t>(PacketType::kData)) {
    std::lock_guard<std::mutex> lock(mu_);
    if (ring_.size() < kKept) {
      ring_.emplace_back(data.begin(), data.end());
    } else {
      ring_[next_].assign(data.begin(), data.end());
    }
    next_ = (next_ + 1) % kKept;
  }
  return inner_->SendTo(to, data);
}

std::vector<std::vector<uint8_t>> RecordingSocket::Recorded() const {
  std::lock_guard<std::mutex> lock(mu_);
  if (ring_.size() < kKept) return ring_;
  std::vector<std::vector<uint8_t>> out;
  for (size_t i = 0; i < kKept; ++i) out.push_back(ring_[(next_ + i) % kKept]);
  return out;
}

namespace {

constexpr uint32_t kPersistent = static_cast<uint32_t>(schema::EntityFlags::Persistent);

void Nap() { std::this_thread::sleep_for(std::chrono::microseconds(500)); }

std::string RejectName(uint16_t reason) {
  if (reason > static_cast<uint16_t>(schema::RejectReason::MAX)) return std::to_string(reason);
  return schema::EnumNameRejectReason(static_cast<schema::RejectReason>(reason));
}

// One attacker connection: joins the room, counts the relay's Error replies by reason into a
// map the attack owns (several connections in turn for churn).
class AttackerClient final : public ClientListener {
 public:
  explicit AttackerClient(std::map<std::string, uint64_t>* errors) : errors_(errors) {}

  // Connects and joins within `timeout_s`; "" or why not.
  std::string Open(const AttackContext& ctx, uint32_t player, ClientConfig cc, double timeout_s) {
    cc.require_packet_auth = false;  // a measurement tool, also against --packet-auth false
    auto socket = UdpSocket::Open(Endpoint(ctx.attacker_address, 0));
    if (!socket.ok()) return "attacker socket: " + socket.status().ToString();
    socket_ = std::move(*socket);
    client_ = std::make_unique<Client>(cc, socket_.get(), this);
    Status st = client_->Connect(ToRelayAddress(ctx.relay->endpoint()), ctx.relay->Token(ctx.room, player), ctx.now());
    if (!st.ok()) return "attacker connect: " + st.ToString();
    const double end = ctx.now() + timeout_s;
    bool join_sent = false;
    while (ctx.now() < end) {
      client_->Update(ctx.now());
      if (client_->state() == ClientState::kConnected && !join_sent) {
        (void)client_->JoinRoom(ctx.room);
        join_sent = true;
      }
      if (client_->joined()) return "";
      if (client_->state() != ClientState::kConnected &&
          client_->state() != ClientState::kHandshaking) {
        break;
      }
      Nap();
    }
    return "attacker did not join (state " + std::to_string(static_cast<int>(client_->state())) +
           ", reject " + RejectName(client_->reject_reason()) + ")";
  }
  Client& client() { return *client_; }
  bool open() const { return client_ != nullptr; }
  // Everything sent was acknowledged (so the relay has answered it, errors included).
  bool Settled() const {
    const ConnectionStats* s = client_ ? client_->stats() : nullptr;
    return s != nullptr && s->pending_reliable_bytes == 0;
  }
  void Close() {
    if (client_) client_->Disconnect();
  }
  void OnError(uint16_t reason, uint32_t, std::string_view) override { ++(*errors_)[RejectName(reason)]; }
  // PhyS-owned entities come back like others': those of this player's id block.
  void OnEntitySpawned(const RemoteEntity& e) override {
    const uint32_t base = client_ ? client_->entity_id_base() : 0;
    if (base != 0 && e.id > base && e.id < base + kEntityIdBlock) ++spawned_seen;
  }
  uint64_t spawned_seen = 0;

 private:
  std::map<std::string, uint64_t>* errors_;
  std::unique_ptr<UdpSocket> socket_;
  std::unique_ptr<Client> client_;
};

// Done once everything is issued and has stayed acknowledged for half a second.
class SettleClock {
 public:
  bool Update(bool issued_all, bool settled, double now) {
    if (!issued_all || !settled) {
      since_ = -1;
      return false;
    }
    if (since_ < 0) since_ = now;
    return now - since_ >= 0.5;
  }

 private:
  double since_ = -1;
};

// Finding 1: offloaded soft bodies, each within the per-body limits.
class PhysicsLoad final : public HostileAttack {
 public:
  std::string Prepare(const AttackContext& ctx) override {
    const HostileOptions& o = *ctx.options;
    ClientConfig cc;
    cc.connection.max_message_size = 4u << 20;  // the relay's own limits decide
    if (std::string e = attacker_.Open(ctx, ctx.first_player, cc, 5.0); !e.empty()) return e;
    physics::BunnyParams bp;
    bp.target_particles = static_cast<int>(o.particles);
    const SoftBodySpec body = physics::MakeBunnySoftBody(bp);
    particles_ = body.particles.size() / 3;
    specs_.push_back(OffloadedSpawn(StaticBox(0, {0, -0.1f, 0}, {10, 0.1f, 10})));
    for (uint32_t i = 0; i < o.soft_bodies; ++i) {
      const float dx = static_cast<float>(i % 5) * 0.9f - 1.8f, dz = static_cast<float>(i / 5) * 0.9f;
      EntitySpec s;
      s.position = {bp.center.x + dx, bp.center.y, bp.center.z + dz};
      s.soft_body = body;
      for (size_t k = 0; k + 2 < s.soft_body->particles.size(); k += 3) {
        s.soft_body->particles[k] += dx;
        s.soft_body->particles[k + 2] += dz;
      }
      specs_.push_back(OffloadedSpawn(s));
    }
    spawn_bytes_ = BuildContainer(specs_.back()).size();
    return "";
  }
  void Step(double now) override {
    attacker_.client().Update(now);
    if (next_ < specs_.size()) {
      auto id = attacker_.client().Spawn(specs_[next_]);
      if (id.ok() || id.status().code() != StatusCode::kQueueFull) {
        if (!id.ok()) ++local_errors_[id.status().ToString()];
        ++next_;
      }
    }
    done_ = settle_.Update(next_ == specs_.size(), attacker_.Settled(), now);
  }
  bool Done(double) const override { return done_; }
  void Idle(double now) override { attacker_.client().Update(now); }
  void Finish() override { attacker_.Close(); }
  nlohmann::json Notes() const override {
    return {{"soft_bodies", specs_.size() - 1}, {"particles_per_body", particles_},
            {"container_bytes_per_body", spawn_bytes_}, {"issued", next_},
            {"relay_errors", errors_}, {"local_errors", local_errors_},
            {"offloaded_entities_seen", attacker_.spawned_seen},
            {"floor", "1 static box, first (counted in issued and seen)"}};
  }

 private:
  std::map<std::string, uint64_t> errors_, local_errors_;
  AttackerClient attacker_{&errors_};
  std::vector<SpawnDesc> specs_;
  size_t next_ = 0, particles_ = 0, spawn_bytes_ = 0;
  SettleClock settle_;
  bool done_ = false;
};

// Finding 2: persistent entities with huge names, then as many small ones as the budgets allow.
class HugeNames final : public HostileAttack {
 public:
  static constexpr uint32_t kFill = 1100;        // past the default 1024 per player
  static constexpr size_t kFillNameBytes = 1000;  // under the default 1024
  std::string Prepare(const AttackContext& ctx) override {
    o_ = ctx.options;
    ClientConfig cc;
    cc.connection.max_message_size = 4u << 20;
    return attacker_.Open(ctx, ctx.first_player, cc, 5.0);
  }
  void Step(double now) override {
    attacker_.client().Update(now);
    const uint32_t total = o_->huge_names + kFill;
    if (issued_ < total) {
      const bool huge = issued_ < o_->huge_names;
      SpawnDesc d{.position = {static_cast<float>(issued_ % 32) * 0.1f, 0, 0}, .flags = kPersistent};
      d.name = std::string(huge ? o_->name_bytes : kFillNameBytes, static_cast<char>('a' + issued_ % 26));
      auto id = attacker_.client().Spawn(d);
      if (id.ok() || id.status().code() != StatusCode::kQueueFull) {
        if (!id.ok()) ++local_errors_[id.status().ToString()];
        ++issued_;
      }
    }
    done_ = settle_.Update(issued_ == total, attacker_.Settled(), now);
  }
  bool Done(double) const override { return done_; }
  void Idle(double now) override { attacker_.client().Update(now); }
  void Finish() override { attacker_.Close(); }
  nlohmann::json Notes() const override {
    return {{"huge_names", o_->huge_names}, {"name_bytes", o_->name_bytes},
            {"fill_entities", kFill}, {"fill_name_bytes", kFillNameBytes}, {"issued", issued_},
            {"relay_errors", errors_}, {"local_errors", local_errors_}};
  }

 private:
  const HostileOptions* o_ = nullptr;
  std::map<std::string, uint64_t> errors_, local_errors_;
  AttackerClient attacker_{&errors_};
  uint32_t issued_ = 0;
  SettleClock settle_;
  bool done_ = false;
};

// Finding 3: one player identity connects, spawns persistent entities and leaves, again and
// again (a fresh token, connection and id block each time).
class Churn final : public HostileAttack {
 public:
  static constexpr uint32_t kPerCycle = 128;
  std::string Prepare(const AttackContext& ctx) override {
    ctx_ = ctx;
    return "";
  }
  void Step(double) override {
    AttackerClient a(&errors_);
    ++cycles_;
    if (std::string e = a.Open(ctx_, ctx_.first_player, ClientConfig{}, 1.5); !e.empty()) {
      ++join_failures_;
      last_failure_ = e;
      a.Close();
      return;
    }
    for (uint32_t i = 0; i < kPerCycle; ++i) {
      SpawnDesc d{.position = {static_cast<float>(i % 16) * 0.1f, 0, 0}, .flags = kPersistent};
      if (a.client().Spawn(d).ok()) ++spawned_;
    }
    const double end = ctx_.now() + 3.0;
    while (ctx_.now() < end && !a.Settled()) {
      a.client().Update(ctx_.now());
      Nap();
    }
    a.Close();
  }
  bool Done(double) const override { return true; }
  void Finish() override {}
  nlohmann::json Notes() const override {
    return {{"cycles", cycles_}, {"join_failures", join_failures_}, {"last_join_failure", last_failure_},
            {"spawns_per_cycle", kPerCycle}, {"spawns_sent", spawned_}, {"relay_errors", errors_}};
  }

 private:
  AttackContext ctx_;
  std::map<std::string, uint64_t> errors_;
  uint64_t cycles_ = 0, join_failures_ = 0, spawned_ = 0;
  std::string last_failure_;
};

// Finding 4: handshake datagrams from another address, as fast as --flood-rate.
class HandshakeFlood final : public HostileAttack {
 public:
  std::string Prepare(const AttackContext& ctx) override {
    if (!ctx.flood_possible) return "skipped: the relay is not on IPv4 loopback";
    auto socket = UdpSocket::Open(Endpoint(ctx.flood_address, 0));
    if (!socket.ok()) return "flood socket on " + ctx.flood_address.to_string() + ": " + socket.status().ToString();
    socket_ = std::move(*socket);
    relay_ = ctx.relay->endpoint();
    rate_ = ctx.options->flood_rate;
    std::mt19937_64 rng(14);
    {
      flatbuffers::FlatBufferBuilder fbb(128);
      FinishControl(fbb, schema::CreateHello(fbb, rng()));
      hello_ = BuildHandshakePacket(PacketType::kHello, fbb, kMinHelloPacketSize);
    }
    std::vector<uint8_t> cookie(48), token(120), key(32);
    for (auto* v : {&cookie, &token, &key}) {
      for (uint8_t& b : *v) b = static_cast<uint8_t>(rng());
    }
    flatbuffers::FlatBufferBuilder fbb(512);
    FinishControl(fbb, schema::CreateConnect(fbb, fbb.CreateVector(cookie), fbb.CreateVector(token),
                                             rng(), fbb.CreateVector(key)));
    connect_ = BuildHandshakePacket(PacketType::kConnect, fbb);
    return "";
  }
  void Step(double now) override {
    if (start_ < 0) start_ = now;
    const double due = rate_ * (now - start_) - static_cast<double>(sent_);
    for (int i = 0; i < std::min(due, 2000.0); ++i) {
      const auto& packet = (sent_ % 2 == 0) ? hello_ : connect_;
      if (socket_->SendTo(relay_, packet).ok()) ++sent_; else ++send_errors_, ++sent_;
    }
    std::array<uint8_t, kMaxDatagramSize> buffer;
    Endpoint from;
    for (int i = 0; i < 4096 && socket_->ReceiveFrom(&from, buffer) > 0; ++i) ++answers_;
    seconds_ = now - start_;
  }
  bool Done(double) const override { return true; }
  void Finish() override {}
  nlohmann::json Notes() const override {
    return {{"datagrams_sent", sent_}, {"send_errors", send_errors_}, {"answers", answers_},
            {"rate_per_s", seconds_ > 0 ? static_cast<double>(sent_) / seconds_ : 0.0},
            {"kinds", "Hello (padded) and Connect (random cookie and token), alternating"}};
  }

 private:
  std::unique_ptr<UdpSocket> socket_;
  Endpoint relay_;
  double rate_ = 0, start_ = -1, seconds_ = 0;
  std::vector<uint8_t> hello_, connect_;
  uint64_t sent_ = 0, send_errors_ = 0, answers_ = 0;
};

// Finding 5: packets with an honest member's exact address and connection id.
class Forged final : public HostileAttack {
 public:
  std::string Prepare(const AttackContext& ctx) override {
    if (ctx.victim == nullptr) return "no victim socket";
    victim_ = ctx.victim;
    relay_ = ctx.relay->endpoint();
    const double end = ctx.now() + 3.0;
    while (ctx.now() < end && victim_->Recorded().empty()) Nap();
    return victim_->Recorded().empty() ? "the victim sent no data packet" : "";
  }
  void Step(double now) override {
    if (now < next_) return;
    next_ = now + 0.05;
    const auto recorded = victim_->Recorded();
    if (recorded.empty()) return;
    const std::vector<uint8_t>& last = recorded.back();
    const uint32_t connection_id =
        last[6] | last[7] << 8 | last[8] << 16 | static_cast<uint32_t>(last[9]) << 24;
    std::vector<uint8_t> disconnect(kConnectionHeaderSize + 1, 0);
    WritePacketPrefix(PacketType::kDisconnect, connection_id, disconnect);
    disconnect.back() = static_cast<uint8_t>(DisconnectReason::kClientLeft);
    if (victim_->Forge(relay_, disconnect).ok()) ++disconnects_;
    std::vector<uint8_t> tampered = last;
    for (size_t i = kPacketPrefixSize + 8; i < tampered.size(); ++i) tampered[i] ^= 0x5a;
    tampered[kPacketPrefixSize + 7] = static_cast<uint8_t>(0x40 + (rounds_ % 64));  // ahead
    if (victim_->Forge(relay_, tampered).ok()) ++tampered_;
    for (const auto& d : recorded) {
      if (victim_->Forge(relay_, d).ok()) ++replays_;
    }
    ++rounds_;
  }
  bool Done(double) const override { return true; }
  void Finish() override {}
  nlohmann::json Notes() const override {
    return {{"rounds", rounds_}, {"unsealed_disconnects", disconnects_},
            {"tampered_data", tampered_}, {"replays", replays_}};
  }

 private:
  RecordingSocket* victim_ = nullptr;
  Endpoint relay_;
  double next_ = 0;
  uint64_t rounds_ = 0, disconnects_ = 0, tampered_ = 0, replays_ = 0;
};

// Finding 6: values no honest client sends.
class InvalidValues final : public HostileAttack {
 public:
  std::string Prepare(const AttackContext& ctx) override {
    if (std::string e = attacker_.Open(ctx, ctx.first_player, ClientConfig{}, 5.0); !e.empty()) return e;
    auto id = attacker_.client().Spawn({.position = {0, 1, 0}});
    if (!id.ok()) return "attacker spawn: " + id.status().ToString();
    own_ = last_id_ = *id;
    return "";
  }
  void Step(double now) override {
    Client& c = attacker_.client();
    c.Update(now);
    if (now < next_) return;
    next_ = now + 0.2;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float inf = std::numeric_limits<float>::infinity();
    auto spawn = [&](SpawnDesc d) {
      auto id = c.Spawn(d);
      if (id.ok()) last_id_ = *id, ++spawns_;
    };
    for (Vec3f scale : {Vec3f{nan, 1, 1}, Vec3f{1, inf, 1}, Vec3f{0, 0, 0}, Vec3f{-1, 1, 1},
                        Vec3f{1e38f, 1, 1}}) {
      spawn({.position = {0, 1, 0}, .scale = scale});
    }
    spawn({.position = {0, 1, 0}, .parent_id = c.entity_id_base() + 60000});  // unknown
    spawn({.position = {0, 1, 0}, .parent_id = last_id_ + 1});               // itself
    flatbuffers::FlatBufferBuilder fbb(64);
    FinishControl(fbb, schema::CreateJoinRoom(fbb, fbb.CreateString("")));
    if (ClientTesting::SendReliableUnchecked(c, {fbb.GetBufferPointer(), fbb.GetSize()}).ok()) ++empty_joins_;
    if (ClientTesting::SendStateUnchecked(c, EntityState{own_, {nan, 1, 0}, {}}, now).ok()) ++nan_states_;
    ++rounds_;
  }
  bool Done(double) const override { return true; }
  void Idle(double now) override { attacker_.client().Update(now); }
  void Finish() override { attacker_.Close(); }
  nlohmann::json Notes() const override {
    return {{"rounds", rounds_}, {"bad_spawns_sent", spawns_}, {"empty_joins", empty_joins_},
            {"nan_states", nan_states_}, {"relay_errors", errors_},
            {"per_round", "5 bad scales (NaN, Inf, 0, -1, 1e38), unknown parent, self parent, "
                          "JoinRoom(\"\"), a NaN state"}};
  }

 private:
  std::map<std::string, uint64_t> errors_;
  AttackerClient attacker_{&errors_};
  uint32_t own_ = 0, last_id_ = 0;
  double next_ = 0;
  uint64_t rounds_ = 0, spawns_ = 0, empty_joins_ = 0, nan_states_ = 0;
};

template <typename T>
std::unique_ptr<HostileAttack> Make() {
  return std::make_unique<T>();
}

}  // namespace

const std::vector<HostileAttackInfo>& HostileAttacks() {
  static const std::vector<HostileAttackInfo> all = {
      {"physics", "offloaded soft bodies (--soft-bodies x --particles)", Make<PhysicsLoad>},
      {"names", "huge-name persistent entities, then fill to the budget; a late joiner", Make<HugeNames>},
      {"churn", "spawn persistent, leave, rejoin, repeat (one identity)", Make<Churn>},
      {"flood", "handshake flood from another loopback address", Make<HandshakeFlood>},
      {"forged", "forged and replayed packets with a member's address and connection id", Make<Forged>},
      {"invalid", "NaN/Inf/0/negative/1e38 scale, bad parents, JoinRoom(\"\"), NaN state", Make<InvalidValues>},
  };
  return all;
}

const HostileAttackInfo* FindHostileAttack(const std::string& name) {
  for (const HostileAttackInfo& a : HostileAttacks()) {
    if (name == a.name) return &a;
  }
  return nullptr;
}

}  // namespace edgephys::loadgen
