// Format 11 streams: convergence of several receivers (each on its own baselines) over links
// with 20 % loss, reordering and duplication; a body at rest sends nothing; forged and stale
// baseline references, capacity bounds and malformed payloads are dropped and counted.
#include "protocol/soft_delta_stream.h"

#include <gtest/gtest.h>

#include <cmath>
#include <deque>
#include <random>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/connection.h"

namespace edgephys {
namespace {

constexpr float kStep = 0.001f;
constexpr uint32_t kBody = 77;

std::vector<Vec3f> RestShape(size_t n) {
  std::vector<Vec3f> p;
  const size_t side = 8;
  for (size_t i = 0; i < n; ++i) {
    p.push_back({0.02f * static_cast<float>(i % side) + 1.0f,
                 0.02f * static_cast<float>((i / side) % side) + 0.5f,
                 0.02f * static_cast<float>(i / (side * side)) - 2.0f});
  }
  return p;
}

// A poke: a bulge pressed in and out while t < poke_s, then the rest shape again.
std::vector<Vec3f> Poked(const std::vector<Vec3f>& rest, double t, double poke_s) {
  std::vector<Vec3f> p = rest;
  if (t >= poke_s) return p;
  const float depth = static_cast<float>(0.05 * std::sin(M_PI * t / poke_s * 3));
  for (size_t i = 0; i < p.size(); ++i) {
    const float d = static_cast<float>(i % 64) / 64.0f;
    p[i].y -= depth * std::exp(-4 * d) + 0.002f * std::sin(static_cast<float>(i) + static_cast<float>(t) * 9);
  }
  return p;
}

struct InFlight {
  double deliver_at;
  uint16_t sequence;
  std::vector<uint8_t> bytes;
};

// One receiver behind a lossy, reordering, duplicating link, with its own sender (as the relay
// keeps one per client).
struct Peer {
  Peer(uint32_t seed, double loss_rate, float threshold)
      : sender({kStep, threshold}), receiver(kStep, 1 << 16), rng(seed), loss(loss_rate) {}
  SoftDeltaSender sender;
  SoftDeltaReceiver receiver;
  std::mt19937 rng;
  double loss;
  uint16_t next_sequence = 0;
  std::deque<InFlight> to_receiver;
  std::deque<InFlight> acks;
  uint64_t bytes = 0;

  bool Chance(double p) { return std::uniform_real_distribution<double>(0, 1)(rng) < p; }
  void Ship(std::span<const uint8_t> payload, double now) {
    const uint16_t seq = next_sequence++;
    sender.OnSent(seq, now);
    bytes += payload.size();
    if (Chance(loss)) return;
    const int copies = Chance(0.1) ? 2 : 1;  // duplication
    for (int c = 0; c < copies; ++c) {
      const double delay = 0.005 + 0.03 * std::uniform_real_distribution<double>(0, 1)(rng);
      to_receiver.push_back({now + delay, seq, {payload.begin(), payload.end()}});
    }
  }
  void Send(const std::vector<Vec3f>& nodes, uint32_t version, double now) {
    const uint32_t time_ms = static_cast<uint32_t>(now * 1000);
    if (!sender.Prepare(kBody, version, nodes, time_ms, now, 0.1)) return;
    std::vector<uint8_t> buf(kMaxUnreliablePayload);
    sender.BeginPayload(buf, time_ms);
    uint32_t first = 0;
    for (int guard = 0; first < nodes.size() && guard < 64; ++guard) {
      if (sender.AddRecords(kBody, &first)) continue;
      const size_t size = sender.FinishPayload();
      ASSERT_GT(size, 0u);
      Ship({buf.data(), size}, now);
      sender.BeginPayload(buf, time_ms);
    }
    const size_t size = sender.FinishPayload();
    if (size > 0) Ship({buf.data(), size}, now);
  }
  void Deliver(double now) {
    // Out of order: anything due, in random order.
    std::shuffle(to_receiver.begin(), to_receiver.end(), rng);
    for (auto it = to_receiver.begin(); it != to_receiver.end();) {
      if (it->deliver_at > now) {
        ++it;
        continue;
      }
      EXPECT_TRUE(receiver.Decode(it->bytes).ok());
      if (!Chance(loss)) acks.push_back({now + 0.01, it->sequence, {}});  // acks are lost too
      it = to_receiver.erase(it);
    }
    for (auto it = acks.begin(); it != acks.end();) {
      if (it->deliver_at > now) {
        ++it;
        continue;
      }
      (void)sender.OnAcked(it->sequence);
      it = acks.erase(it);
    }
  }
};

double MaxError(std::span<const Vec3f> shown, const std::vector<Vec3f>& truth) {
  if (shown.size() != truth.size()) return 1e9;
  double worst = 0;
  for (size_t i = 0; i < truth.size(); ++i) {
    const double dx = shown[i].x - truth[i].x, dy = shown[i].y - truth[i].y, dz = shown[i].z - truth[i].z;
    worst = std::max(worst, std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  return worst;
}

TEST(SoftDeltaStream, ReceiversOnTheirOwnBaselinesConvergeUnderLossReorderingAndDuplication) {
  const std::vector<Vec3f> rest = RestShape(510);
  std::vector<std::unique_ptr<Peer>> peers;
  for (uint32_t s = 0; s < 3; ++s) peers.push_back(std::make_unique<Peer>(100 + s, 0.2, 0.0f));
  const double dt = 1.0 / 60;
  uint32_t version = 0;
  bool baselines_differed = false;
  std::vector<Vec3f> truth;
  for (int tick = 0; tick < 360; ++tick) {
    const double now = tick * dt;
    truth = Poked(rest, now, 3.0);
    if (tick <= 180 || tick == 200) ++version;  // moves for 3 s, one more change, then rests
    for (size_t k = 0; k < peers.size(); ++k) {
      if (tick % (k + 1) == 0) peers[k]->Send(truth, version, now);  // 60, 30, 20 Hz
      peers[k]->Deliver(now);
    }
    if (peers[0]->sender.AckedVersion(kBody) != peers[1]->sender.AckedVersion(kBody)) {
      baselines_differed = true;
    }
  }
  EXPECT_TRUE(baselines_differed);
  for (auto& p : peers) {
    // The receiver ends exactly on the lattice point of the truth (threshold 0).
    const auto shown = p->receiver.Display(kBody);
    ASSERT_EQ(shown.size(), truth.size());
    for (size_t i = 0; i < truth.size(); ++i) {
      ASSERT_EQ(shown[i].x, static_cast<float>(SoftLattice(truth[i].x, kStep) * double{kStep}));
      ASSERT_EQ(shown[i].y, static_cast<float>(SoftLattice(truth[i].y, kStep) * double{kStep}));
      ASSERT_EQ(shown[i].z, static_cast<float>(SoftLattice(truth[i].z, kStep) * double{kStep}));
    }
    EXPECT_LE(MaxError(shown, truth), 0.87 * kStep + 1e-6);
    // Nothing was decoded against a baseline it did not hold, nothing malformed.
    EXPECT_EQ(p->receiver.stats().unknown_baseline, 0u);
    EXPECT_EQ(p->receiver.stats().malformed, 0u);
    EXPECT_GT(p->receiver.stats().records, 20u);
    EXPECT_GT(p->sender.stats().records, p->sender.stats().keyframes * 3);  // mostly deltas
  }
}

TEST(SoftDeltaStream, ABodyAtRestCostsNothingAndSmallJitterIsNotSent) {
  const std::vector<Vec3f> rest = RestShape(510);
  Peer p(1, 0.0, 0.001f);
  uint32_t version = 1;
  p.Send(rest, version, 0.0);
  p.Deliver(0.05);
  p.Deliver(0.07);
  ASSERT_EQ(p.sender.AckedVersion(kBody), 1u);
  const uint64_t before = p.bytes;
  for (int tick = 0; tick < 120; ++tick) {  // sub-threshold jitter, a new version every tick
    std::vector<Vec3f> jitter = rest;
    for (size_t i = 0; i < jitter.size(); ++i) jitter[i].x += 0.0003f * std::sin(static_cast<float>(tick + i));
    p.Send(jitter, ++version, 0.1 + tick / 60.0);
    p.Deliver(0.1 + tick / 60.0);
  }
  EXPECT_EQ(p.bytes, before);
  EXPECT_EQ(p.sender.stats().settled, 120u);
  // A real move is sent, as a small delta.
  std::vector<Vec3f> moved = rest;
  for (auto& v : moved) v.y += 0.004f;
  p.Send(moved, ++version, 3.0);
  EXPECT_GT(p.bytes, before);
  EXPECT_LT(p.bytes - before, 60u);
}

TEST(SoftDeltaStream, UnacknowledgedVersionIsResentAfterTheTimeout) {
  const std::vector<Vec3f> rest = RestShape(100);
  Peer p(2, 1.0, 0.001f);  // everything lost
  p.Send(rest, 1, 0.0);
  const uint64_t once = p.bytes;
  p.Send(rest, 1, 0.05);  // within resend_after (0.1 s): nothing
  EXPECT_EQ(p.bytes, once);
  p.Send(rest, 1, 0.2);
  EXPECT_GE(p.bytes, 2 * once);  // the same record, its age now two varint bytes
  EXPECT_LE(p.bytes, 2 * once + 1);
  EXPECT_EQ(p.sender.stats().resends, 1u);
}

// Builds a payload with one record of `version` against `base` (0: keyframe).
std::vector<uint8_t> Record(const std::vector<Vec3f>& nodes, uint32_t version, uint32_t time_ms,
                            const std::vector<Vec3f>* base, uint32_t base_version) {
  std::vector<int32_t> q, b;
  for (const Vec3f& v : nodes) {
    for (float c : {v.x, v.y, v.z}) q.push_back(SoftLattice(c, kStep));
  }
  if (base != nullptr) {
    for (const Vec3f& v : *base) {
      for (float c : {v.x, v.y, v.z}) b.push_back(SoftLattice(c, kStep));
    }
  }
  std::vector<uint8_t> out(kMaxUnreliablePayload);
  size_t pos = BeginSoftDeltaPayload(time_ms, out);
  SoftDeltaScratch scratch;
  SoftDeltaRecordInput in{.entity_id = kBody, .version = version, .age_ms = 0, .q = q, .first = 0,
                          .max_count = static_cast<uint32_t>(nodes.size())};
  if (base != nullptr) {
    in.refs.base = b;
    in.refs.base_distance = version - base_version;
  }
  uint32_t count = 0;
  pos += EncodeSoftDeltaRecord(in, std::span<uint8_t>(out).subspan(pos), &scratch, &count, nullptr);
  out.resize(pos);
  return out;
}

TEST(SoftDeltaStream, ForgedAndStaleBaselinesAreDroppedAndCounted) {
  const std::vector<Vec3f> rest = RestShape(64);
  std::vector<Vec3f> moved = rest;
  for (auto& v : moved) v.y += 0.01f;
  SoftDeltaReceiver r(kStep, 1 << 16);
  ASSERT_TRUE(r.Decode(Record(rest, 3, 100, nullptr, 0)).ok());
  const std::vector<Vec3f> shown(r.Display(kBody).begin(), r.Display(kBody).end());
  EXPECT_LE(MaxError(shown, rest), 0.87 * kStep);

  // A delta against version 2, which the receiver never had: dropped, counted, nothing shown.
  ASSERT_TRUE(r.Decode(Record(moved, 5, 200, &rest, 2)).ok());
  EXPECT_EQ(r.stats().unknown_baseline, 1u);
  EXPECT_TRUE(r.updates().empty());
  EXPECT_LE(MaxError(r.Display(kBody), rest), 0.87 * kStep);
  // Against version 3, which it holds: applied.
  ASSERT_TRUE(r.Decode(Record(moved, 5, 200, &rest, 3)).ok());
  EXPECT_EQ(r.updates().size(), 1u);
  EXPECT_LE(MaxError(r.Display(kBody), moved), 0.87 * kStep);

  // Fill the history with higher versions; a record older than all of them is stale.
  for (uint32_t v = 10; v < 10 + kSoftHistory; ++v) ASSERT_TRUE(r.Decode(Record(moved, v, 300, nullptr, 0)).ok());
  EXPECT_EQ(r.HeldVersions(kBody).size(), kSoftHistory);
  EXPECT_EQ(r.HeldVersions(kBody).front(), 10u);
  ASSERT_TRUE(r.Decode(Record(rest, 4, 300, nullptr, 0)).ok());
  EXPECT_EQ(r.stats().stale, 1u);
  // Evicted version 3 can no longer be referenced.
  ASSERT_TRUE(r.Decode(Record(moved, 40, 400, &rest, 3)).ok());
  EXPECT_EQ(r.stats().unknown_baseline, 2u);
  // An older version than the one displayed is stored but does not replace the display.
  ASSERT_TRUE(r.Decode(Record(rest, 30, 400, nullptr, 0)).ok());
  ASSERT_TRUE(r.Decode(Record(moved, 20, 400, nullptr, 0)).ok());
  EXPECT_TRUE(r.updates().empty());
  EXPECT_LE(MaxError(r.Display(kBody), rest), 0.87 * kStep);
}

TEST(SoftDeltaStream, PartialVersionIsNoBaselineForParticlesItLacks) {
  const std::vector<Vec3f> rest = RestShape(600);
  std::vector<Vec3f> moved = rest;
  for (auto& v : moved) v.z += 0.003f;
  // A keyframe of 600 particles needs two payloads; deliver only the first.
  SoftDeltaSender s({kStep, 0.0f});
  ASSERT_TRUE(s.Prepare(kBody, 1, rest, 0, 0, 0.1));
  std::vector<uint8_t> buf(400);
  s.BeginPayload(buf, 0);
  uint32_t first = 0;
  while (s.AddRecords(kBody, &first)) {}
  ASSERT_LT(first, 600u);
  std::vector<uint8_t> part(buf.begin(), buf.begin() + static_cast<ptrdiff_t>(s.FinishPayload()));
  SoftDeltaReceiver r(kStep, 1 << 16);
  ASSERT_TRUE(r.Decode(part).ok());
  // A whole-body delta against version 1 (forged: version 1 was never fully acknowledged).
  ASSERT_TRUE(r.Decode(Record(moved, 2, 10, &rest, 1)).ok());
  EXPECT_EQ(r.stats().unknown_baseline, 1u);
}

TEST(SoftDeltaStream, BoundsAndMalformedPayloadsAreCounted) {
  const std::vector<Vec3f> rest = RestShape(64);
  SoftDeltaReceiver r(kStep, 1 << 16, /*max_bodies=*/1, /*max_held_particles=*/64 * 3);
  ASSERT_TRUE(r.Decode(Record(rest, 1, 0, nullptr, 0)).ok());
  ASSERT_TRUE(r.Decode(Record(rest, 2, 0, nullptr, 0)).ok());
  ASSERT_TRUE(r.Decode(Record(rest, 3, 0, nullptr, 0)).ok());
  ASSERT_TRUE(r.Decode(Record(rest, 4, 0, nullptr, 0)).ok());  // a fourth version: over the bound
  EXPECT_EQ(r.stats().over_capacity, 1u);
  std::vector<uint8_t> other = Record(rest, 1, 0, nullptr, 0);
  other[5] = 78;  // another body id: over max_bodies
  ASSERT_TRUE(r.Decode(other).ok());
  EXPECT_EQ(r.stats().over_capacity, 2u);

  std::vector<uint8_t> good = Record(rest, 9, 0, nullptr, 0);
  EXPECT_FALSE(r.Decode(std::span<const uint8_t>(good.data(), 3)).ok());   // short header
  EXPECT_FALSE(r.Decode(std::span<const uint8_t>(good.data(), 5)).ok());   // no record
  EXPECT_FALSE(r.Decode(std::span<const uint8_t>(good.data(), 12)).ok());  // truncated
  std::vector<uint8_t> wrong = good;
  wrong[0] = 5;
  EXPECT_FALSE(r.Decode(wrong).ok());
  EXPECT_EQ(r.stats().malformed, 4u);
  std::mt19937 rng(4);
  for (int i = 0; i < 3000; ++i) {
    std::vector<uint8_t> junk(1 + rng() % 80);
    for (auto& b : junk) b = static_cast<uint8_t>(rng());
    junk[0] = kSoftDeltaFormat;
    (void)r.Decode(junk);
    for (const SoftDeltaUpdate& u : r.updates()) {
      ASSERT_LE(size_t{u.first} + u.count, r.Display(u.id).size());
    }
  }
  r.Forget(kBody);
  EXPECT_TRUE(r.Display(kBody).empty());
}

}  // namespace
}  // namespace edgephys
