// Lockstep receivers (relay/lockstep.h) through the real RoomHost, Room and ClientReplicator:
// players publish moving entities, every receiver's replicator ticks at 60 Hz over the room's
// frame, and each receiver's datagrams cross a simulated link (loss, duplication, reordering,
// lost and late acknowledgements) to a format-9 decoder that drops stale packets as the
// connection does. What must hold: every receiver ends within 1 mm / 0.1 deg of every entity,
// no decoder ever meets a reference it does not hold (missing or future), and the lockstep
// paths (copies, leaves, rejoins) are exercised.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
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

struct LinkModel {
  double loss = 0;         // datagrams lost
  double duplicate = 0;    // datagrams delivered twice
  int max_delay_ticks = 0; // each datagram 0..this many ticks late (reordering)
  double ack_loss = 0;     // acknowledgements lost
  int ack_delay_min = 0, ack_delay_max = 0;  // ticks until an acknowledgement reaches the relay
};

struct Packets final : PacketWriter {
  std::vector<std::vector<uint8_t>> packets;
  void WritePacket(std::span<const uint8_t> p) override { packets.emplace_back(p.begin(), p.end()); }
};

// One receiver: the relay's replicator and connection for it, the link, and its decoder.
struct Receiver {
  Receiver(uint32_t player, const ReplicationConfig& config, const QuantizationParams& q,
           LinkModel model, uint64_t seed)
      : self(player), replicator(std::make_unique<ClientReplicator>(config)),
        connection(player, ConnectionConfig{}, 0.0), link(model), rng(seed), decoder(q) {}
  uint32_t self;
  std::unique_ptr<ClientReplicator> replicator;
  Connection connection;
  Packets out;
  LinkModel link;
  std::mt19937_64 rng;
  SharedDeltaDecoder decoder;
  struct InFlight {
    int64_t at;
    std::vector<uint8_t> bytes;
  };
  std::vector<InFlight> packets;
  std::vector<std::pair<int64_t, uint16_t>> acks;  // (tick it reaches the relay, sequence)
  bool have_newest = false;
  uint16_t newest = 0;
  std::map<uint32_t, EntityState> shown;  // newest decoded state per entity
  int64_t drop_sequence_from = -1;        // tests: the first datagram at or after this tick is lost
  int64_t dropped_at = -1;                // the tick it was sent in
  int64_t ack_hold_ticks = 0;             // tests: and/or its acknowledgement held this long
  uint16_t held_sequence = 0;
  bool holding = false;
  int64_t ticks_in_lockstep = 0;  // ticks whose replicator tick sent canonical copies
};

class LockstepTest : public RoomHostTest {
 protected:
  LockstepTest() {
    config_.capacity = 32;
    config_.max_entities_per_player = 8;
    config_.tick_rate_hz = 60;
    config_.replication.shared_encoding = true;
    config_.replication.shared_lockstep = true;
    config_.replication.lockstep_ack_ticks = 3;
    host_ = std::make_unique<RoomHost>("r", config_, RoomHostEnv{&limits_, &counters_, &placement_},
                                       0.0);
    q_ = *MakeQuantizationParams(QuantizationOf(config_.replication));
  }

  // A player joins with one hand (48 Hz) and two boxes (12 Hz), and a receiver for it.
  Receiver& AddPlayer(uint32_t player, LinkModel link) {
    members_.push_back(std::make_unique<RecordingMember>(player));
    RecordingMember& m = *members_.back();
    EXPECT_TRUE(host_->Join(m, Now()));
    for (uint32_t k = 1; k <= 3; ++k) {
      Spawn(m, LocalBox(Base(m) + k, player, k == 1 ? kHandFlag : 0));
      owned_[player].push_back(Base(m) + k);
    }
    receivers_.push_back(std::make_unique<Receiver>(player, config_.replication, q_, link,
                                                    1000 + player));
    return *receivers_.back();
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
    for (size_t i = 0; i < receivers_.size(); ++i) {
      if (receivers_[i]->self == player) receivers_.erase(receivers_.begin() + static_cast<long>(i));
    }
  }

  void DespawnOne(uint32_t player) {
    auto& ids = owned_[player];
    if (ids.empty()) return;
    const uint32_t id = ids.back();
    ids.pop_back();
    for (auto& m : members_) {
      if (m->player_id() == player) host_->Despawn(*m, id);
    }
    ForgetAll({id});
  }

  void ForgetAll(const std::vector<uint32_t>& ids) {
    for (uint32_t id : ids) {
      for (auto& r : receivers_) {
        r->replicator->Forget(id);
        r->decoder.Forget(id);
        r->shown.erase(id);
      }
    }
  }

  double Now() const { return 1.0 + static_cast<double>(tick_) * kTick; }

  // The pose of entity `id` at time t (moving until `moving_until_`).
  EntityState Pose(uint32_t id, double t) const {
    const double u = std::min(t, moving_until_);
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

  // One room tick: owners publish, due acknowledgements reach the relay, the room ticks (the
  // lockstep group first), every receiver's replicator ticks, datagrams travel.
  void Step() {
    const double now = Now();
    for (auto& m : members_) {
      std::vector<EntityState> states;
      for (uint32_t id : owned_[m->player_id()]) states.push_back(Pose(id, now));
      host_->ApplyStates(*m, StatePayload(states), now);
    }
    for (auto& r : receivers_) DeliverAcks(*r);
    std::vector<MemberLink*> links;
    host_->BeginTick(now, &links);
    for (auto& r : receivers_) {
      r->out.packets.clear();
      r->replicator->Tick(host_->room().frame(), r->self, now, r->connection, r->out, counters_);
      r->ticks_in_lockstep += r->replicator->in_lockstep() ? 1 : 0;
      for (auto& p : r->out.packets) Send(*r, std::move(p));
    }
    ++tick_;
    for (auto& r : receivers_) DeliverPackets(*r);
  }

  void Send(Receiver& r, std::vector<uint8_t> bytes) {
    std::uniform_real_distribution<double> u(0, 1);
    const uint16_t seq = LoadU16LE(bytes.data() + kPacketPrefixSize);
    if (r.drop_sequence_from >= 0 && tick_ >= r.drop_sequence_from) {
      r.drop_sequence_from = -1;
      r.dropped_at = tick_;
      if (r.ack_hold_ticks == 0) return;  // lost
      r.holding = true;                   // delivered, its acknowledgement held
      r.held_sequence = seq;
    } else if (u(r.rng) < r.link.loss) {
      return;
    }
    const int copies = u(r.rng) < r.link.duplicate ? 2 : 1;
    for (int c = 0; c < copies; ++c) {
      const int delay = r.link.max_delay_ticks > 0
                            ? static_cast<int>(r.rng() % (r.link.max_delay_ticks + 1))
                            : 0;
      r.packets.push_back({tick_ + delay, bytes});
    }
  }

  void DeliverPackets(Receiver& r) {
    std::uniform_real_distribution<double> u(0, 1);
    std::vector<Receiver::InFlight> later;
    for (auto& p : r.packets) {
      if (p.at > tick_) {
        later.push_back(std::move(p));
        continue;
      }
      const uint16_t seq = LoadU16LE(p.bytes.data() + kPacketPrefixSize);
      // The connection delivers only payloads newer than every one delivered (and acks those).
      if (r.have_newest && !SequenceGreater(seq, r.newest)) continue;
      r.have_newest = true;
      r.newest = seq;
      const uint8_t* payload = p.bytes.data() + kConnectionHeaderSize + 3;
      const uint16_t size = LoadU16LE(payload - 2);
      StateBatch batch;
      if (payload[0] == kSharedDeltaStateFormat) {
        EXPECT_TRUE(r.decoder.Decode({payload, size}, &batch).ok());
        for (const EntityState& s : batch.states) r.shown[s.entity_id] = s;
      }
      if (r.holding && seq == r.held_sequence) {
        r.acks.push_back({tick_ + r.ack_hold_ticks, seq});
        r.holding = false;
        continue;
      }
      if (u(r.rng) < r.link.ack_loss) continue;
      const int d = r.link.ack_delay_min +
                    (r.link.ack_delay_max > r.link.ack_delay_min
                         ? static_cast<int>(r.rng() % (r.link.ack_delay_max - r.link.ack_delay_min + 1))
                         : 0);
      r.acks.push_back({tick_ + d, seq});
    }
    r.packets.swap(later);
  }

  void DeliverAcks(Receiver& r) {
    std::vector<std::pair<int64_t, uint16_t>> later;
    for (auto [at, seq] : r.acks) {
      if (at > tick_) {
        later.push_back({at, seq});
      } else {
        r.replicator->OnPacketAcked(seq);
      }
    }
    r.acks.swap(later);
  }

  // Every receiver holds every live entity within 1 mm / 0.1 deg of its pose, and never met a
  // reference it did not hold.
  void ExpectConverged() {
    const double now = Now();
    if (std::getenv("LOCKSTEP_TEST_VERBOSE") != nullptr) {
      std::printf("sends %lu leaves %lu rejoins %lu updates %lu ticks %lu\n",
                  static_cast<unsigned long>(counters_.lockstep_sends.load()),
                  static_cast<unsigned long>(counters_.lockstep_leaves.load()),
                  static_cast<unsigned long>(counters_.lockstep_rejoins.load()),
                  static_cast<unsigned long>(counters_.entity_updates_sent.load()),
                  static_cast<unsigned long>(tick_));
      for (auto& r : receivers_) {
        std::printf("  receiver %u: payloads %lu entities %lu keyframes %lu unresolved %lu "
                    "ticks in lockstep %ld\n",
                    r->self, static_cast<unsigned long>(r->decoder.stats().payloads),
                    static_cast<unsigned long>(r->decoder.stats().entities),
                    static_cast<unsigned long>(r->decoder.stats().keyframes),
                    static_cast<unsigned long>(r->decoder.stats().unresolved_references),
                    static_cast<long>(r->ticks_in_lockstep));
      }
    }
    for (auto& r : receivers_) {
      const SharedDeltaDecoderStats& st = r->decoder.stats();
      EXPECT_EQ(st.missing_references, 0u) << "receiver " << r->self;
      EXPECT_EQ(st.future_references, 0u) << "receiver " << r->self;
      EXPECT_EQ(st.malformed, 0u) << "receiver " << r->self;
      for (const auto& [player, ids] : owned_) {
        for (uint32_t id : ids) {
          auto it = r->shown.find(id);
          ASSERT_NE(it, r->shown.end()) << "receiver " << r->self << " entity " << id;
          const EntityState want = Pose(id, now);
          const Vec3f& p = it->second.position;
          const double dx = p.x - want.position.x, dy = p.y - want.position.y,
                       dz = p.z - want.position.z;
          EXPECT_LE(std::sqrt(dx * dx + dy * dy + dz * dz), 0.001)
              << "receiver " << r->self << " entity " << id;
          const Quatf& a = it->second.rotation;
          const Quatf& b = want.rotation;
          const double dot = std::fabs(a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w) /
                             std::sqrt((a.x * a.x + a.y * a.y + a.z * a.z + a.w * a.w) *
                                       (b.x * b.x + b.y * b.y + b.z * b.z + b.w * b.w));
          EXPECT_LE(2 * std::acos(std::min(1.0, dot)) * 180 / 3.14159265358979, 0.1 + 1e-3)
              << "receiver " << r->self << " entity " << id;
        }
      }
    }
  }

  Receiver* ReceiverOf(uint32_t player) {
    for (auto& r : receivers_) {
      if (r->self == player) return r.get();
    }
    return nullptr;
  }

  QuantizationParams q_;
  int64_t tick_ = 0;
  double moving_until_ = 1e9;
  std::vector<std::unique_ptr<RecordingMember>> members_;
  std::vector<std::unique_ptr<Receiver>> receivers_;
  std::map<uint32_t, std::vector<uint32_t>> owned_;
};

LinkModel Clean() { return LinkModel{0, 0, 0, 0, 1, 1}; }
LinkModel Lossy() { return LinkModel{0.2, 0.1, 3, 0.2, 1, 3}; }

// Twelve receivers, half on clean links and half with 20 % loss, duplication, reordering and lost
// and late acknowledgements; motion stops for the last 3 s.
TEST_F(LockstepTest, CleanAndLossyReceiversAllConvergeWithNoUnheldReference) {
  for (uint32_t p = 1; p <= 12; ++p) AddPlayer(p, p % 2 == 0 ? Lossy() : Clean());
  moving_until_ = Now() + 6.0;
  for (int i = 0; i < 9 * 60; ++i) Step();
  ExpectConverged();
  EXPECT_GT(counters_.lockstep_sends.load(), 0u);
  EXPECT_GT(counters_.lockstep_leaves.load(), 0u);
  EXPECT_GT(counters_.lockstep_rejoins.load(), 0u);
  // The clean receivers spend most ticks in lockstep.
  for (auto& r : receivers_) {
    if (r->self % 2 == 1) {
      EXPECT_GT(r->ticks_in_lockstep, tick_ * 8 / 10) << "receiver " << r->self;
    }
  }
}

// A lockstep receiver loses one canonical payload (no acknowledgement ever): it leaves lockstep
// at the start of the tick that would first reference that payload's versions, never meets a
// reference it does not hold, and converges. Fails if the leave rule is removed (its decoder
// counts missing references: the payload's versions become the canonical baselines).
TEST_F(LockstepTest, AReceiverMissingAPayloadLeavesBeforeItIsReferenced) {
  for (uint32_t p = 1; p <= 4; ++p) AddPlayer(p, Clean());
  for (int i = 0; i < 120; ++i) Step();
  Receiver& r = *ReceiverOf(2);
  ASSERT_TRUE(r.replicator->in_lockstep());
  moving_until_ = Now() + 1.5;
  const uint64_t leaves = counters_.lockstep_leaves.load();
  // Forged acknowledgements of sequences it was never sent change nothing.
  for (uint16_t s = 30000; s < 30100; ++s) r.replicator->OnPacketAcked(s);
  r.drop_sequence_from = tick_;
  for (int i = 0; i < 10 && r.dropped_at < 0; ++i) Step();
  ASSERT_GE(r.dropped_at, 0);
  // In lockstep until the tick lockstep_ack_ticks (3) after the lost one, and out of it at the
  // start of that tick, before its payloads are built.
  while (tick_ < r.dropped_at + 3) {
    EXPECT_TRUE(r.replicator->in_lockstep()) << "tick " << tick_;
    Step();
  }
  Step();
  EXPECT_FALSE(r.replicator->in_lockstep());
  EXPECT_EQ(counters_.lockstep_leaves.load(), leaves + 1);
  for (int i = 0; i < 240; ++i) Step();
  ExpectConverged();
  EXPECT_GT(counters_.lockstep_rejoins.load(), 4u);  // back in (4 initial joins, then this one)
  EXPECT_TRUE(r.replicator->in_lockstep());
}

// A lockstep receiver gets a payload but its acknowledgement comes 10 ticks late: it leaves at
// the due tick all the same, and converges.
TEST_F(LockstepTest, ALateAcknowledgementLeavesAtTheDueTick) {
  for (uint32_t p = 1; p <= 4; ++p) AddPlayer(p, Clean());
  for (int i = 0; i < 120; ++i) Step();
  Receiver& r = *ReceiverOf(3);
  ASSERT_TRUE(r.replicator->in_lockstep());
  moving_until_ = Now() + 1.5;
  const uint64_t leaves = counters_.lockstep_leaves.load();
  r.drop_sequence_from = tick_;
  r.ack_hold_ticks = 10;
  for (int i = 0; i < 4; ++i) Step();
  EXPECT_FALSE(r.replicator->in_lockstep());
  EXPECT_EQ(counters_.lockstep_leaves.load(), leaves + 1);
  for (int i = 0; i < 240; ++i) Step();
  ExpectConverged();
}

// Joins, leaves and despawns while receivers are in lockstep, some links lossy.
TEST_F(LockstepTest, JoinsLeavesAndDespawnsMidStream) {
  for (uint32_t p = 1; p <= 6; ++p) AddPlayer(p, p == 3 ? Lossy() : Clean());
  moving_until_ = Now() + 8.0;
  for (int i = 0; i < 11 * 60; ++i) {
    if (i == 60) AddPlayer(7, Clean());
    if (i == 90) AddPlayer(8, Lossy());
    if (i == 120) RemovePlayer(2);
    if (i == 150) DespawnOne(4);
    if (i == 200) AddPlayer(9, Clean());  // may reuse the departed player's entity slots
    if (i == 240) DespawnOne(1);
    if (i == 300) RemovePlayer(7);
    if (i == 330) AddPlayer(10, Clean());
    Step();
  }
  ExpectConverged();
  EXPECT_GT(counters_.lockstep_rejoins.load(), 8u);
  EXPECT_TRUE(ReceiverOf(10)->replicator->in_lockstep());
}

}  // namespace
}  // namespace edgephys::room_host_testing
