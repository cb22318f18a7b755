// Format 9's one-pass walk (ClientReplicator::TickSharedEntities, relay/replication_shared_walk.cc)
// against the general two-pass walk it replaces when there is no bandwidth budget: through the
// real RoomHost, Room and ClientReplicator, every receiver has two replicators, one of each
// walk, fed the same frames, the same `now` and the same acknowledgements (lossy links, late
// and lost acks), while players join, leave, despawn, move and stop. What must hold: the two
// send the same datagrams, byte for byte, in every tick (the wire of format 9 does not depend
// on the walk), including ticks whose records fill more than one datagram, and a format-9
// decoder fed the one-pass datagrams ends within 1 mm of every entity.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/sequence.h"
#include "relay/replication.h"
#include "relay/room_host_testing.h"

namespace edgephys::room_host_testing {
namespace {

constexpr double kTick = 1.0 / 60;
constexpr uint32_t kHandFlag = 1u << 4;  // schema::EntityFlags::Hand: critical, 48 Hz
constexpr uint32_t kEntitiesPerPlayer = 16;

struct Packets final : PacketWriter {
  std::vector<std::vector<uint8_t>> packets;
  void WritePacket(std::span<const uint8_t> p) override { packets.emplace_back(p.begin(), p.end()); }
};

// One receiver, twice: the one-pass walk (`one`) and the two-pass walk (`two`).
struct Twin {
  Twin(uint32_t player, const ReplicationConfig& config, const QuantizationParams& q, double loss,
       uint64_t seed)
      : self(player), one(std::make_unique<ClientReplicator>(config)),
        two(std::make_unique<ClientReplicator>(config)), one_connection(player, ConnectionConfig{}, 0.0),
        two_connection(player, ConnectionConfig{}, 0.0), loss(loss), rng(seed), decoder(q) {
    two->UseTwoPassWalkForTesting();
  }
  uint32_t self;
  std::unique_ptr<ClientReplicator> one, two;
  Connection one_connection, two_connection;
  Packets one_out, two_out;
  double loss;
  std::mt19937_64 rng;
  SharedDeltaDecoder decoder;
  std::vector<std::pair<int64_t, uint16_t>> acks;  // (tick it reaches the relay, sequence)
  std::map<uint32_t, EntityState> shown;
};

class WalkTest : public RoomHostTest {
 protected:
  WalkTest() {
    config_.capacity = 64;
    config_.max_entities_per_player = 16;
    config_.tick_rate_hz = 60;
    config_.replication.mode = ReplicationMode::kEdgephys;
    config_.replication.shared_encoding = true;  // the default; no lockstep, no budget
    host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                       0.0);
    q_ = *MakeQuantizationParams(QuantizationOf(config_.replication));
  }

  // A player with kEntitiesPerPlayer entities, two thirds of them critical (48 Hz), the rest
  // at the normal rate (12 Hz), and its receiver.
  void AddPlayer(uint32_t player, double loss) {
    members_.push_back(std::make_unique<RecordingMember>(player));
    RecordingMember& m = *members_.back();
    ASSERT_TRUE(host_->Join(m, Now()));
    for (uint32_t k = 1; k <= kEntitiesPerPlayer; ++k) {
      Spawn(m, LocalBox(Base(m) + k, player, k % 3 != 0 ? kHandFlag : 0));
      owned_[player].push_back(Base(m) + k);
    }
    twins_.push_back(std::make_unique<Twin>(player, config_.replication, q_, loss, 77 + player));
  }

  void RemovePlayer(uint32_t player) {
    for (size_t i = 0; i < members_.size(); ++i) {
      if (members_[i]->player_id() != player) continue;
      host_->Leave(*members_[i], Now());
      ForgetAll(owned_[player]);
      owned_.erase(player);
      members_.erase(members_.begin() + static_cast<long>(i));
      break;
    }
    for (size_t i = 0; i < twins_.size(); ++i) {
      if (twins_[i]->self == player) twins_.erase(twins_.begin() + static_cast<long>(i));
    }
  }

  void DespawnOne(uint32_t player) {
    auto& ids = owned_[player];
    const uint32_t id = ids.back();
    ids.pop_back();
    for (auto& m : members_) {
      if (m->player_id() == player) host_->Despawn(*m, id);
    }
    ForgetAll({id});
  }

  void ForgetAll(const std::vector<uint32_t>& ids) {
    for (uint32_t id : ids) {
      for (auto& t : twins_) {
        t->one->Forget(id);
        t->two->Forget(id);
        t->decoder.Forget(id);
        t->shown.erase(id);
      }
    }
  }

  double Now() const { return 1.0 + static_cast<double>(tick_) * kTick; }

  // The pose of entity `id` at time t: moving until `moving_until_`, and the third of every
  // player's entities with id % 3 == 1 only every other second (they settle and start again).
  EntityState Pose(uint32_t id, double t) const {
    double u = std::min(t, moving_until_);
    if (id % 3 == 1) u = std::floor(u) + std::min(1.0, 2.0 * (u - std::floor(u)));
    const double w = 0.7 + 0.05 * (id % 11), ph = 0.37 * (id % 17);
    EntityState s;
    s.entity_id = id;
    s.position = {static_cast<float>(0.4 * std::cos(w * u + ph) + 0.1 * (id % 7)),
                  static_cast<float>(1.2 + 0.2 * std::sin(1.3 * w * u)),
                  static_cast<float>(0.4 * std::sin(w * u + ph) - 0.05 * (id % 5))};
    const double a = 0.5 * w * u + ph;
    s.rotation = {0, static_cast<float>(std::sin(a / 2)), 0, static_cast<float>(std::cos(a / 2))};
    return s;
  }

  // One room tick: owners publish (every other tick, as at 30 Hz), due acknowledgements reach
  // both replicators of every receiver, the room ticks, both replicators tick and their
  // datagrams are compared; the one-pass datagrams travel to the decoder.
  void Step() {
    const double now = Now();
    if (tick_ % 2 == 0) {
      for (auto& m : members_) {
        std::vector<EntityState> states;
        for (uint32_t id : owned_[m->player_id()]) states.push_back(Pose(id, now));
        host_->ApplyStates(*m, StatePayload(states), now);
      }
    }
    for (auto& t : twins_) {
      std::vector<std::pair<int64_t, uint16_t>> later;
      for (auto [at, seq] : t->acks) {
        if (at > tick_) {
          later.push_back({at, seq});
          continue;
        }
        t->one->OnPacketAcked(seq);
        t->two->OnPacketAcked(seq);
      }
      t->acks.swap(later);
    }
    std::vector<MemberLink*> links;
    host_->BeginTick(now, &links);
    // Every 7th tick the receivers tick 4 ms after the room's frame was scheduled: the one-pass
    // walk must then not take the room's next due times (ReplicationFrame::next_due), which
    // are for the frame's time.
    const double rnow = tick_ % 7 == 3 ? now + 0.004 : now;
    for (auto& t : twins_) {
      t->one_out.packets.clear();
      t->two_out.packets.clear();
      t->one->Tick(host_->room().frame(), t->self, rnow, t->one_connection, t->one_out, counters_);
      t->two->Tick(host_->room().frame(), t->self, rnow, t->two_connection, t->two_out, counters_);
      ASSERT_EQ(t->one_out.packets.size(), t->two_out.packets.size())
          << "receiver " << t->self << " tick " << tick_;
      for (size_t i = 0; i < t->one_out.packets.size(); ++i) {
        ASSERT_EQ(t->one_out.packets[i], t->two_out.packets[i])
            << "receiver " << t->self << " tick " << tick_ << " datagram " << i;
      }
      datagrams_ += t->one_out.packets.size();
      if (t->one_out.packets.size() > 1) ++multi_datagram_ticks_;
      for (const auto& p : t->one_out.packets) Deliver(*t, p);
    }
    ++tick_;
  }

  // Loses the datagram with the twin's probability; else decodes it and acknowledges it 1-3
  // ticks later (20 % of acknowledgements lost on lossy links).
  void Deliver(Twin& t, const std::vector<uint8_t>& bytes) {
    std::uniform_real_distribution<double> u(0, 1);
    if (u(t.rng) < t.loss) return;
    const uint16_t seq = LoadU16LE(bytes.data() + kPacketPrefixSize);
    const uint8_t* payload = bytes.data() + kConnectionHeaderSize + 3;
    const uint16_t size = LoadU16LE(payload - 2);
    StateBatch batch;
    if (payload[0] == kSharedDeltaStateFormat) {
      EXPECT_TRUE(t.decoder.Decode({payload, size}, &batch).ok());
      for (const EntityState& s : batch.states) t.shown[s.entity_id] = s;
    }
    if (t.loss > 0 && u(t.rng) < 0.2) return;
    t.acks.push_back({tick_ + 1 + static_cast<int64_t>(t.rng() % 3), seq});
  }

  QuantizationParams q_;
  int64_t tick_ = 0;
  double moving_until_ = 1e9;
  uint64_t datagrams_ = 0;
  uint64_t multi_datagram_ticks_ = 0;
  std::vector<std::unique_ptr<RecordingMember>> members_;
  std::vector<std::unique_ptr<Twin>> twins_;
  std::map<uint32_t, std::vector<uint32_t>> owned_;
};

// 32 players of 16 entities (a tick's records fill more than one datagram), a third of the
// receivers with 20 % loss and lost acknowledgements; players join, leave (their slots reused)
// and despawn mid-stream; motion stops for the last 2 s. Fails if the one-pass walk decides,
// orders, splits or schedules any record differently from the two-pass walk (including when it
// takes the room's next due times for a tick they were not computed for).
TEST_F(WalkTest, OnePassSendsTheTwoPassDatagramsByteForByte) {
  for (uint32_t p = 1; p <= 32; ++p) AddPlayer(p, p % 3 == 0 ? 0.2 : 0.0);
  moving_until_ = Now() + 6.0;
  for (int i = 0; i < 8 * 60; ++i) {
    if (i == 60) RemovePlayer(5);
    if (i == 90) DespawnOne(7);
    if (i == 120) AddPlayer(33, 0.2);  // may reuse the departed player's entity slots
    if (i == 150) DespawnOne(1);
    if (i == 200) RemovePlayer(12);
    if (i == 230) AddPlayer(34, 0.0);
    Step();
    if (HasFatalFailure()) return;
  }
  EXPECT_GT(datagrams_, 32u * 8 * 30);
  EXPECT_GT(multi_datagram_ticks_, 100u);  // payloads split mid-walk (Flush, Begin)
  // The clean receivers hold every other player's entity within the lattice (the stream
  // converges).
  for (auto& t : twins_) {
    if (t->loss > 0) continue;
    EXPECT_EQ(t->decoder.stats().missing_references, 0u);
    EXPECT_EQ(t->decoder.stats().future_references, 0u);
    for (const auto& [player, ids] : owned_) {
      if (player == t->self) continue;  // its own entities are not sent to it
      for (uint32_t id : ids) {
        auto it = t->shown.find(id);
        ASSERT_NE(it, t->shown.end()) << "receiver " << t->self << " entity " << id;
        const EntityState want = Pose(id, Now());
        const Vec3f& p = it->second.position;
        const double dx = p.x - want.position.x, dy = p.y - want.position.y,
                     dz = p.z - want.position.z;
        EXPECT_LE(std::sqrt(dx * dx + dy * dy + dz * dz), 0.001)
            << "receiver " << t->self << " entity " << id;
      }
    }
  }
}

}  // namespace
}  // namespace edgephys::room_host_testing
