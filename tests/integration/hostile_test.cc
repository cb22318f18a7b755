// Hostile clients against a live relay on loopback (issue 14): what one player with a valid
// join token can do to a room must not make the room unjoinable.
#include <gtest/gtest.h>

#include <algorithm>
#include <map>

#include "client/client_endpoint.h"
#include "loadgen/scenes/scenes.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

constexpr uint32_t kPersistent = static_cast<uint32_t>(schema::EntityFlags::Persistent);

// Finding 2: persistent entities with huge names (each under --max-spawn-bytes) summed past a
// joiner's reliable queue, and every late joiner was disconnected with ReliableOverflow. The
// join now streams paced within the joiner's reliable budget.
TEST(Hostile, HugeRoomStateStreamsToALateJoinerInsteadOfOverflowingIt) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.connection.max_pending_reliable_bytes = 4u << 20;  // the relay's queue per client
  config.limits.bytes_per_s = 0;
  config.limits.packets_per_s = 0;
  config.room_defaults.budgets.max_name_bytes = 300000;  // the attack's names, allowed here
  LoopbackWorld world(config);
  Client& attacker = world.AddClient(MintToken("r", 1));
  ASSERT_TRUE(world.RunUntil([&] { return attacker.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(attacker.JoinRoom("r").ok());
  ASSERT_TRUE(world.RunUntil([&] { return attacker.joined(); }, 3.0));
  constexpr int kEntities = 18;  // 18 x 250 KB = 4.5 MB > the joiner's 4 MB queue
  for (int i = 0; i < kEntities; ++i) {
    auto id = attacker.Spawn({.position = {float(i), 0, 0}, .flags = kPersistent,
                              .name = std::string(250000, char('a' + i))});
    ASSERT_TRUE(id.ok()) << id.status().ToString();
    ASSERT_TRUE(world.RunUntil([&] { return world.relay().FindRoom("r")->entities().size() ==
                                            size_t(i + 1); }, 5.0)) << i;
  }
  Client& joiner = world.AddClient(MintToken("r", 2));
  ASSERT_TRUE(world.RunUntil([&] { return joiner.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(joiner.JoinRoom("r").ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return joiner.entities().size() == kEntities || joiner.state() != ClientState::kConnected;
  }, 20.0));
  EXPECT_EQ(joiner.state(), ClientState::kConnected)
      << "disconnected: " << static_cast<int>(joiner.disconnect_reason());
  EXPECT_EQ(joiner.entities().size(), size_t(kEntities));
  EXPECT_EQ(world.counters().disconnects[size_t(DisconnectReason::kReliableOverflow)].load(), 0u);
}

// Counts one entity's updates and the longest wait between two of them; and Error replies.
struct UpdateWatch : ClientListener {
  uint32_t entity = 0;
  double start = -1, last = -1, max_gap = 0;
  uint64_t updates = 0;
  std::map<uint16_t, uint64_t> errors;
  std::function<double()> now;
  void OnEntityUpdated(const RemoteEntity& e) override {
    if (e.id != entity || start < 0) return;
    const double t = now();
    max_gap = std::max(max_gap, t - (last >= 0 ? last : start));
    last = t;
    ++updates;
  }
  void OnError(uint16_t reason, uint32_t, std::string_view) override { ++errors[reason]; }
  void Begin(double t) { start = t, last = -1, max_gap = 0, updates = 0; }
  double Gap(double t) const { return std::max(max_gap, t - (last >= 0 ? last : start)); }
};

// Finding 1, live: one player offloads 20 soft bodies of ~4,096 particles (each within the
// per-body limits) into its room. The room's PhyS budget (default 8,192 particles per player)
// refuses all but what fits, each refusal an OverBudget Error and a counted reason, and an
// honest client in another room keeps receiving its peer's updates throughout (a generous
// bound on the longest gap; the rate ratio is measured by `edgephys-loadgen hostile`).
TEST(Hostile, SoftBodyLoadIsRefusedByBudgetWhileAnotherRoomKeepsReceiving) {
  RelayConfig config = LoopbackWorld::DefaultConfig();  // default budgets
  config.physics_threads = 2;    // PhyS off the relay's loop, as on a 2-core host
  config.limits.bytes_per_s = 0;  // the attack's ~10 MB arrive at once: the budget must hold
  LoopbackWorld world(config);
  UpdateWatch attacker_watch, b_watch;
  attacker_watch.now = b_watch.now = [&] { return world.Now(); };
  Client& attacker = world.AddClient(MintToken("a", 1), &attacker_watch);
  Client& b_sender = world.AddClient(MintToken("b", 2));
  Client& b_receiver = world.AddClient(MintToken("b", 3), &b_watch);
  for (auto [c, room] : {std::pair{&attacker, "a"}, {&b_sender, "b"}, {&b_receiver, "b"}}) {
    ASSERT_TRUE(world.RunUntil([&] { return c->state() == ClientState::kConnected; }, 5.0));
    ASSERT_TRUE(c->JoinRoom(room).ok());
  }
  ASSERT_TRUE(world.RunUntil([&] {
    return attacker.joined() && b_sender.joined() && b_receiver.joined();
  }, 5.0));
  auto id = b_sender.Spawn({.position = {0, 1, 0}});
  ASSERT_TRUE(id.ok());
  b_watch.entity = *id;
  auto wave = [&](double now) {
    (void)b_sender.PublishTransform(*id, {static_cast<float>(std::sin(3 * now)), 1, 0}, {});
  };
  b_watch.Begin(world.Now());
  world.RunFor(1.0, wave);
  ASSERT_GT(b_watch.updates, 5u) << "room B's receiver gets no steady stream";

  // The attack, built beforehand so the pump is not held up building it.
  physics::BunnyParams bp;
  bp.target_particles = 4096;
  const SoftBodySpec body = physics::MakeBunnySoftBody(bp);
  const size_t particles = body.particles.size() / 3;
  ASSERT_GT(particles, 3500u);
  ASSERT_LE(particles, 4600u);
  const uint32_t offloaded = static_cast<uint32_t>(schema::EntityFlags::Offloaded);
  SpawnDesc floor{.position = {0, -0.1f, 0}, .flags = offloaded};
  floor.colliders.push_back(BoxCollider({10, 0.1f, 10}));
  ASSERT_TRUE(attacker.Spawn(floor).ok());
  std::vector<SpawnDesc> bodies(20, SpawnDesc{.flags = offloaded});
  for (size_t i = 0; i < bodies.size(); ++i) {
    bodies[i].soft_body = body;
    for (size_t k = 0; k < body.particles.size(); k += 3) {
      bodies[i].soft_body->particles[k] += static_cast<float>(i % 5) * 0.9f;
      bodies[i].soft_body->particles[k + 2] += static_cast<float>(i / 5) * 0.9f;
    }
  }
  const size_t fit = config.room_defaults.budgets.max_particles_per_player / particles;
  const uint64_t refused_before =
      world.counters().budget_refusals[static_cast<size_t>(BudgetKind::kPlayerParticles)].load();
  const uint64_t steps_before = RelayCounters::Get(world.counters().physics_steps);
  const uint16_t over_budget = static_cast<uint16_t>(schema::RejectReason::OverBudget);
  size_t next = 0;
  b_watch.Begin(world.Now());
  const bool answered = world.RunUntil([&] {
    wave(world.Now());
    if (next < bodies.size()) {
      auto spawned = attacker.Spawn(bodies[next]);
      if (spawned.ok()) {
        ++next;
      } else {
        EXPECT_EQ(spawned.status().code(), StatusCode::kQueueFull) << spawned.status().ToString();
      }
    }
    return next == bodies.size() && attacker_watch.errors[over_budget] >= bodies.size() - fit;
  }, 60.0);
  world.RunFor(3.0, wave);  // the accepted bodies simulate; B keeps going
  const double gap = b_watch.Gap(world.Now());
  const double seconds = world.Now() - b_watch.start;
  std::printf("soft bodies of %zu particles: %zu fit, %llu refused; room B: %llu updates in %.1f s, "
              "longest gap %.3f s\n", particles, fit,
              static_cast<unsigned long long>(attacker_watch.errors[over_budget]),
              static_cast<unsigned long long>(b_watch.updates), seconds, gap);
  ASSERT_TRUE(answered) << "the relay did not answer every spawn";
  EXPECT_EQ(attacker_watch.errors[over_budget], bodies.size() - fit);
  EXPECT_EQ(attacker_watch.errors.size(), 1u) << "refused for another reason too";
  EXPECT_EQ(world.counters().budget_refusals[static_cast<size_t>(BudgetKind::kPlayerParticles)]
                    .load() - refused_before, bodies.size() - fit);
  EXPECT_GE(RequestsRejected(world.counters(), schema::RejectReason::OverBudget), bodies.size() - fit);
  EXPECT_LE(world.relay().FindRoom("a")->ledger().Of(1).particles, 8192u);
  EXPECT_GT(RelayCounters::Get(world.counters().physics_steps), steps_before) << "PhyS stopped";
  // Room B throughout: still connected, updates all along (1 s is ~30 ticks at 30 Hz).
  EXPECT_EQ(b_receiver.state(), ClientState::kConnected);
  EXPECT_LT(gap, 1.0) << "room B's receiver waited " << gap << " s for an update";
  EXPECT_GT(static_cast<double>(b_watch.updates), 5.0 * seconds);
}

// Records what a client sends (its sealed datagrams) and lets the test send from the very same
// address, as an on-path attacker spoofing the victim would.
class RecordingSocket final : public DatagramSocket {
 public:
  explicit RecordingSocket(std::unique_ptr<UdpSocket> inner) : inner_(std::move(inner)) {}
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    if (data.size() > kPacketPrefixSize && data[5] == static_cast<uint8_t>(PacketType::kData)) {
      sent.emplace_back(data.begin(), data.end());
    }
    return inner_->SendTo(to, data);
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    return inner_->ReceiveFrom(from, buffer);
  }
  Endpoint LocalEndpoint() const override { return inner_->LocalEndpoint(); }
  Status Forge(const Endpoint& to, std::span<const uint8_t> data) { return inner_->SendTo(to, data); }
  std::vector<std::vector<uint8_t>> sent;

 private:
  std::unique_ptr<UdpSocket> inner_;
};

// Finding 5: a packet forged with the victim's exact address and connection id ended its
// session and despawned its entities. Every packet after the handshake is now sealed: forged
// and replayed packets are dropped, counted, and change nothing.
TEST(Hostile, ForgedAndReplayedPacketsFromTheVictimsAddressChangeNothing) {
  LoopbackWorld world;
  RecordingSocket victim_socket(
      std::move(*UdpSocket::Open(Endpoint(world.relay_endpoint().address(), 0))));
  Client victim(ClientConfig{}, &victim_socket);
  ASSERT_TRUE(victim.Connect(ToRelayAddress(world.relay_endpoint()), MintToken("r", 1), world.Now()).ok());
  Client& other = world.AddClient(MintToken("r", 2));
  auto pump = [&](double seconds, const std::function<bool()>& done) {
    return world.RunUntil([&] {
      victim.Update(world.Now());
      return done();
    }, seconds);
  };
  uint32_t id = 0;
  ASSERT_NO_FATAL_FAILURE(JoinVictimAndSpawn(pump, victim, other, "r", &id));
  ASSERT_FALSE(victim_socket.sent.empty());
  const std::vector<uint8_t> real = victim_socket.sent.back();
  const uint32_t connection_id = real[6] | real[7] << 8 | real[8] << 16 | uint32_t(real[9]) << 24;

  // 1. An unsealed Disconnect with the exact address and connection id (what ended the
  //    session before), and Data packets with garbage in place of the seal.
  std::vector<uint8_t> disconnect(kConnectionHeaderSize + 1, 0);
  WritePacketPrefix(PacketType::kDisconnect, connection_id, disconnect);
  disconnect.back() = static_cast<uint8_t>(DisconnectReason::kClientLeft);
  const uint64_t bad_auth = Rejected(world.counters(), DropReason::kBadAuth);
  for (int i = 0; i < 3; ++i) ASSERT_TRUE(victim_socket.Forge(world.relay_endpoint(), disconnect).ok());
  std::vector<uint8_t> forged = real;
  for (size_t i = kPacketPrefixSize + 8; i < forged.size(); ++i) forged[i] ^= 0x5a;
  forged[kPacketPrefixSize + 7] = 0x7f;  // a fresh sequence: past the replay check
  ASSERT_TRUE(victim_socket.Forge(world.relay_endpoint(), forged).ok());
  // 2. Replays of every packet the victim sent so far.
  const uint64_t replayed = Rejected(world.counters(), DropReason::kReplayed);
  for (const auto& d : std::vector<std::vector<uint8_t>>(victim_socket.sent)) {
    ASSERT_TRUE(victim_socket.Forge(world.relay_endpoint(), d).ok());
  }
  const size_t replays = victim_socket.sent.size();
  pump(0.5, [] { return false; });
  EXPECT_EQ(Rejected(world.counters(), DropReason::kBadAuth) - bad_auth, 4u);
  // Replays inside the window and older ones are both refused as replays.
  EXPECT_EQ(Rejected(world.counters(), DropReason::kReplayed) - replayed, replays);
  EXPECT_EQ(victim.state(), ClientState::kConnected);
  EXPECT_EQ(world.relay().session_count(), 2u);
  EXPECT_EQ(world.relay().FindRoom("r")->entities().count(id), 1u);
  EXPECT_EQ(other.entities().count(id), 1u);
  // The victim's session still works.
  ASSERT_TRUE(victim.PublishTransform(id, {4, 5, 6}, {}).ok());
  EXPECT_TRUE(pump(3.0, [&] {
    auto it = other.entities().find(id);
    return it != other.entities().end() && std::abs(it->second.state.position.x - 4) < 0.01f;
  }));
}

// With --packet-auth false (measurement only) the relay accepts unsealed connections, from
// clients that allow it (ClientConfig::require_packet_auth false, as the harness sets for such
// a relay). A client with the default setting refuses the relay and says why.
TEST(Hostile, PacketAuthCanBeTurnedOffForMeasurement) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.packet_auth = false;
  LoopbackWorld world(config);
  Client& a = world.AddClient(MintToken("r", 1));
  ASSERT_TRUE(world.RunUntil([&] { return a.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(a.JoinRoom("r").ok());
  EXPECT_TRUE(world.RunUntil([&] { return a.joined(); }, 3.0));

  auto socket = std::move(*UdpSocket::Open(Endpoint(world.relay_endpoint().address(), 0)));
  Client strict(ClientConfig{}, socket.get());
  ASSERT_TRUE(strict.Connect(ToRelayAddress(world.relay_endpoint()), MintToken("r", 2), world.Now()).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    strict.Update(world.Now());
    return strict.state() != ClientState::kHandshaking;
  }, 3.0));
  EXPECT_EQ(strict.state(), ClientState::kRejected);
  EXPECT_EQ(strict.reject_reason(), static_cast<uint16_t>(schema::RejectReason::AuthRequired));
  // It told the relay: the session the relay had opened for it is gone at once.
  EXPECT_TRUE(world.RunUntil([&] { return world.relay().session_count() == 1; }, 2.0));
}

// Rewrites the relay's Accept on its way to the client without the relay's key, as an on-path
// attacker downgrading the session to unauthenticated packets would.
class KeyStrippingSocket final : public DatagramSocket {
 public:
  explicit KeyStrippingSocket(std::unique_ptr<UdpSocket> inner) : inner_(std::move(inner)) {}
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    return inner_->SendTo(to, data);
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    const size_t n = inner_->ReceiveFrom(from, buffer);
    if (n <= kPacketPrefixSize || buffer[5] != static_cast<uint8_t>(PacketType::kAccept)) return n;
    const auto* msg = VerifyControlMessage(buffer.subspan(kPacketPrefixSize, n - kPacketPrefixSize));
    if (msg == nullptr || msg->body_type() != schema::Body::Accept) return n;
    const auto* a = msg->body_as_Accept();
    flatbuffers::FlatBufferBuilder fbb(128);
    FinishControl(fbb, schema::CreateAccept(fbb, a->connection_id(), a->player_id(),
                                            a->keepalive_ms(), a->timeout_ms()));
    const std::vector<uint8_t> packet = BuildHandshakePacket(PacketType::kAccept, fbb);
    std::copy(packet.begin(), packet.end(), buffer.begin());
    ++stripped;
    return packet.size();
  }
  Endpoint LocalEndpoint() const override { return inner_->LocalEndpoint(); }
  int stripped = 0;

 private:
  std::unique_ptr<UdpSocket> inner_;
};

// The downgrade: the relay seals, but its key is stripped from the Accept on the way. Before
// ClientConfig::require_packet_auth the SDK then talked unsealed (and forged packets would have
// been its to accept); now the connect fails with AuthRequired and nothing is sent unsealed.
TEST(Hostile, AStrippedRelayKeyFailsTheConnectInsteadOfDowngrading) {
  LoopbackWorld world;
  auto connect = [&](bool require, KeyStrippingSocket* socket, uint32_t player) {
    ClientConfig cc;
    cc.require_packet_auth = require;
    auto c = std::make_unique<Client>(cc, socket);
    EXPECT_TRUE(c->Connect(ToRelayAddress(world.relay_endpoint()), MintToken("r", player), world.Now()).ok());
    EXPECT_TRUE(world.RunUntil([&] {
      c->Update(world.Now());
      return c->state() != ClientState::kHandshaking;
    }, 3.0));
    return c;
  };
  auto open = [&] {
    return std::make_unique<KeyStrippingSocket>(
        std::move(*UdpSocket::Open(Endpoint(world.relay_endpoint().address(), 0))));
  };
  auto strict_socket = open();
  auto strict = connect(true, strict_socket.get(), 1);
  EXPECT_GE(strict_socket->stripped, 1);
  EXPECT_EQ(strict->state(), ClientState::kRejected);
  EXPECT_EQ(strict->reject_reason(), static_cast<uint16_t>(schema::RejectReason::AuthRequired));
  EXPECT_EQ(strict->JoinRoom("r").code(), StatusCode::kNotConnected);
  // What the option prevents: a client that allows it accepts the downgraded session.
  auto lax_socket = open();
  auto lax = connect(false, lax_socket.get(), 2);
  EXPECT_GE(lax_socket->stripped, 1);
  EXPECT_EQ(lax->state(), ClientState::kConnected);
}

}  // namespace
}  // namespace edgephys::testing
