// State format 12 (format 2 plus velocities): round trips over random inputs, loss, reordering
// and duplicates, forged input, and the sender's dead-reckoning test (NeedExtrapolated).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <random>
#include <vector>

#include "protocol/bit_stream.h"
#include "protocol/byte_io.h"
#include "protocol/connection.h"
#include "protocol/delta_codec.h"
#include "protocol/testing/codec_test_util.h"

namespace edgephys {
namespace {

using namespace testing_util;  // NOLINT(google-build-using-namespace): test helpers

QuantizationParams Params() {
  QuantizationConfig qc;
  qc.bounds_min = {-50, -5, -50};
  qc.bounds_max = {50, 20, 50};
  auto p = MakeQuantizationParams(qc);
  EXPECT_TRUE(p.ok());
  return *p;
}

DeltaEncoderOptions WithVelocities() {
  DeltaEncoderOptions o;
  o.velocities = true;
  return o;
}

// The velocity a decoder must output for `v`: each component rounded to the lattice, clamped
// to +-kMaxVelocityIndex steps, 0 if not finite.
float Expected(float v, double step) {
  if (!std::isfinite(v)) return 0.f;
  const double x = std::clamp(std::round(v / step), -double{kMaxVelocityIndex},
                              double{kMaxVelocityIndex});
  return static_cast<float>(x * step);
}

void ExpectVelocity(const EntityVelocity& got, const EntityVelocity& sent) {
  const float lin[3] = {sent.linear.x, sent.linear.y, sent.linear.z};
  const float ang[3] = {sent.angular.x, sent.angular.y, sent.angular.z};
  const float glin[3] = {got.linear.x, got.linear.y, got.linear.z};
  const float gang[3] = {got.angular.x, got.angular.y, got.angular.z};
  for (int a = 0; a < 3; ++a) {
    ASSERT_EQ(glin[a], Expected(lin[a], kLinearVelocityStep)) << a;
    ASSERT_EQ(gang[a], Expected(ang[a], kAngularVelocityStep)) << a;
    if (std::isfinite(lin[a]) && std::fabs(lin[a]) < 60) {
      ASSERT_LE(std::fabs(glin[a] - lin[a]), kLinearVelocityStep / 2 + 1e-6);
    }
  }
}

EntityVelocity RandomVelocity(std::mt19937_64& rng) {
  EntityVelocity v;
  switch (rng() % 6) {
    case 0: return v;  // at rest
    case 1: {          // out of range and not finite: clamped, zeroed
      const float nan = std::numeric_limits<float>::quiet_NaN();
      v.linear = {500.f, -1e9f, nan};
      v.angular = {std::numeric_limits<float>::infinity(), -300.f, 0.001f};
      return v;
    }
    default: {
      std::uniform_real_distribution<float> lin(-8, 8), ang(-20, 20);
      v.linear = {lin(rng), lin(rng), lin(rng)};
      v.angular = {ang(rng), ang(rng), ang(rng)};
      if (rng() % 3 == 0) v.angular = {};  // sliding without turning
      return v;
    }
  }
}

TEST(DeltaVelocityCodec, RandomStatesAndVelocitiesRoundTripWithinBounds) {
  const QuantizationParams params = Params();
  std::mt19937_64 rng(23);
  DeltaEncoder enc(params, WithVelocities());
  DeltaDecoder dec(params);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  std::uniform_real_distribution<float> ux(-50, 50), uy(-5, 20), small(-0.2f, 0.2f);
  std::vector<EntityState> state(32);  // keyframes with velocities: ~30 bytes each
  std::vector<EntityVelocity> velocity(state.size());
  for (size_t i = 0; i < state.size(); ++i) {
    state[i].entity_id = static_cast<uint32_t>(3 + i * 5);
    state[i].position = {ux(rng), uy(rng), ux(rng)};
    state[i].rotation = RandomRotation(rng);
  }
  StateBatch batch;
  for (int round = 0; round < 500; ++round) {
    for (size_t i = 0; i < state.size(); ++i) {
      EntityState& s = state[i];
      if (rng() % 5 == 0) {
        s.position = {ux(rng), uy(rng), ux(rng)};
        s.rotation = RandomRotation(rng);
      } else {
        s.position.x = std::clamp(s.position.x + small(rng), -50.f, 50.f);
      }
      velocity[i] = RandomVelocity(rng);
    }
    enc.Begin(buf, static_cast<uint32_t>(round * 17));
    for (size_t i = 0; i < state.size(); ++i) {
      const bool at_rest = rng() % 7 == 0;  // nullptr: at rest
      if (at_rest) velocity[i] = {};
      ASSERT_TRUE(enc.Add(state[i], nullptr, at_rest ? nullptr : &velocity[i]));
    }
    const size_t size = enc.Finish();
    ASSERT_GT(size, 0u);
    ASSERT_EQ(buf[0], kVelocityDeltaStateFormat);
    enc.OnSent(static_cast<uint16_t>(round), round * 0.017);
    batch.states.clear();
    batch.velocities.clear();
    ASSERT_TRUE(dec.Decode({buf.data(), size}, &batch).ok());
    ASSERT_EQ(batch.states.size(), state.size());
    ASSERT_EQ(batch.velocities.size(), state.size());
    if (rng() % 4 != 0) enc.OnPacketAcked(static_cast<uint16_t>(round));
    for (size_t i = 0; i < state.size(); ++i) {
      ASSERT_LE(PositionError(batch.states[i].position, state[i].position),
                params.step * std::sqrt(3.0) / 2 + FloatSlack(60));
      ASSERT_LE(RotationErrorDeg(batch.states[i].rotation, state[i].rotation),
                params.config.rotation_error_deg);
      ExpectVelocity(batch.velocities[i], velocity[i]);
    }
  }
  EXPECT_EQ(dec.stats().unresolved_references, 0u);
  EXPECT_EQ(dec.stats().malformed, 0u);
}

// Velocities exactly as added (to the lattice), per record, whatever the order of arrival.
TEST(DeltaVelocityCodec, LossReorderAndDuplicatesKeepEachStatesOwnVelocity) {
  const QuantizationParams params = Params();
  for (uint64_t seed : {1, 2, 3, 4}) {
    std::mt19937_64 rng(seed);
    DeltaEncoder enc(params, WithVelocities());
    DeltaDecoder dec(params);
    std::vector<std::vector<uint8_t>> payloads;
    // Per payload: entity -> (state, velocity) added.
    std::vector<std::map<uint32_t, std::pair<EntityState, EntityVelocity>>> added;
    std::vector<EntityState> state(12);
    for (size_t i = 0; i < state.size(); ++i) {
      state[i].entity_id = static_cast<uint32_t>(100 + i);
      state[i].position = {static_cast<float>(i), 1.f, 0.f};
      state[i].rotation = RandomRotation(rng);
    }
    std::vector<uint8_t> buf(kMaxUnreliablePayload);
    std::vector<size_t> in_flight;  // payload indices not yet delivered
    StateBatch batch;
    std::map<uint32_t, int64_t> newest_seen;  // entity -> payload index last output
    for (int round = 0; round < 300; ++round) {
      enc.Begin(buf, static_cast<uint32_t>(round * 16));
      std::map<uint32_t, std::pair<EntityState, EntityVelocity>> rec;
      for (EntityState& s : state) {
        if (rng() % 3 == 0) continue;  // not every entity in every payload
        s.position.x += 0.01f * static_cast<float>(rng() % 9);
        const EntityVelocity v = RandomVelocity(rng);
        ASSERT_TRUE(enc.Add(s, nullptr, &v));
        rec[s.entity_id] = {s, v};
      }
      const size_t size = enc.Finish();
      if (size == 0) continue;
      enc.OnSent(static_cast<uint16_t>(payloads.size()), round * 0.016);
      payloads.emplace_back(buf.begin(), buf.begin() + static_cast<long>(size));
      added.push_back(std::move(rec));
      in_flight.push_back(payloads.size() - 1);
      // Deliver a random subset of what is in flight, in random order; some twice, some never.
      std::shuffle(in_flight.begin(), in_flight.end(), rng);
      std::vector<size_t> keep;
      for (size_t idx : in_flight) {
        const uint64_t fate = rng() % 10;
        if (fate < 2) {
          keep.push_back(idx);  // later
          continue;
        }
        if (fate == 2) continue;  // lost (never acknowledged)
        for (int copy = 0; copy < (fate == 3 ? 2 : 1); ++copy) {
          batch.states.clear();
          batch.velocities.clear();
          ASSERT_TRUE(dec.Decode(payloads[idx], &batch).ok());
          ASSERT_EQ(batch.velocities.size(), batch.states.size());
          for (size_t i = 0; i < batch.states.size(); ++i) {
            const uint32_t id = batch.states[i].entity_id;
            auto it = added[idx].find(id);
            ASSERT_NE(it, added[idx].end());
            ASSERT_LE(PositionError(batch.states[i].position, it->second.first.position),
                      params.step * std::sqrt(3.0) / 2 + FloatSlack(60));
            ExpectVelocity(batch.velocities[i], it->second.second);
            auto seen = newest_seen.find(id);
            ASSERT_TRUE(seen == newest_seen.end() || seen->second < static_cast<int64_t>(idx));
            newest_seen[id] = static_cast<int64_t>(idx);
          }
        }
        enc.OnPacketAcked(static_cast<uint16_t>(idx));
      }
      in_flight = std::move(keep);
    }
    EXPECT_GT(dec.stats().entities, 500u) << seed;
    EXPECT_EQ(dec.stats().malformed, 0u);
  }
}

// A format-12 payload with one keyframe record whose first linear component is `index`.
std::vector<uint8_t> Forged(const QuantizationParams& p, int32_t index) {
  std::vector<uint8_t> out(64, 0);
  out[0] = kVelocityDeltaStateFormat;
  StoreU32LE(out.data() + 1, 1000);
  StoreU16LE(out.data() + 5, 1);
  // k = 2, 1; no masks; order 0; velocity k index 0 (k = 1) for both groups.
  StoreU16LE(out.data() + 7, static_cast<uint16_t>(2 | (1 << 3)));
  out[kDeltaHeaderSize] = 1;  // count
  BitWriter w(std::span<uint8_t>(out).subspan(kDeltaHeaderSize + 1));
  EXPECT_TRUE(w.WriteExpGolomb(5, 0));  // id
  EXPECT_TRUE(w.WriteExpGolomb(1, 0));  // keyframe
  for (int a = 0; a < 3; ++a) EXPECT_TRUE(w.WriteBits(p.max_index[a] / 2, p.position_bits[a]));
  EXPECT_TRUE(w.WriteBits(3, 2));
  for (int c = 0; c < 3; ++c) EXPECT_TRUE(w.WriteBits(static_cast<uint32_t>(p.rotation_max), p.rotation_bits));
  EXPECT_TRUE(w.WriteBit(true));  // moving
  EXPECT_TRUE(w.WriteSigned(index, 1));
  for (int a = 0; a < 5; ++a) EXPECT_TRUE(w.WriteSigned(0, 1));
  out.resize(kDeltaHeaderSize + 1 + w.byte_size());
  return out;
}

TEST(DeltaVelocityCodec, ForgedAndGarbageInputIsCountedAndDropped) {
  const QuantizationParams params = Params();
  DeltaDecoder dec(params);
  StateBatch batch;
  // The forger's own payload decodes; the same with an index beyond the range does not.
  ASSERT_TRUE(dec.Decode(Forged(params, 1000), &batch).ok());
  ASSERT_EQ(batch.velocities.size(), 1u);
  EXPECT_FLOAT_EQ(batch.velocities[0].linear.x, static_cast<float>(1000 * kLinearVelocityStep));
  batch = {};
  EXPECT_FALSE(dec.Decode(Forged(params, kMaxVelocityIndex + 1), &batch).ok());
  EXPECT_TRUE(batch.states.empty() && batch.velocities.empty());
  EXPECT_EQ(dec.stats().malformed, 1u);

  // Every truncation of a real payload, and random bytes behind a format-12 header.
  DeltaEncoder enc(params, WithVelocities());
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  enc.Begin(buf, 5);
  std::mt19937_64 rng(9);
  for (uint32_t id = 1; id < 30; ++id) {
    EntityState s;
    s.entity_id = id;
    s.rotation = RandomRotation(rng);
    const EntityVelocity v = RandomVelocity(rng);
    ASSERT_TRUE(enc.Add(s, nullptr, &v));
  }
  const size_t size = enc.Finish();
  uint64_t malformed = dec.stats().malformed;
  for (size_t n = 0; n < size; ++n) {
    batch = {};
    EXPECT_FALSE(dec.Decode({buf.data(), n}, &batch).ok()) << n;
    EXPECT_EQ(dec.stats().malformed, ++malformed);
  }
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<uint8_t> junk(1 + rng() % 200);
    for (uint8_t& b : junk) b = static_cast<uint8_t>(rng());
    junk[0] = kVelocityDeltaStateFormat;
    batch = {};
    const bool ok = dec.Decode(junk, &batch).ok();
    EXPECT_EQ(batch.velocities.size(), batch.states.size());
    for (const EntityVelocity& v : batch.velocities) {
      EXPECT_LE(std::fabs(v.linear.x), kMaxVelocityIndex * kLinearVelocityStep);
    }
    if (!ok) {
      EXPECT_TRUE(batch.states.empty());
    }
  }
}

TEST(DeltaVelocityCodec, FormatTwoIsUnchangedAndStillDecoded) {
  const QuantizationParams params = Params();
  DeltaEncoder enc(params);  // no velocities: format 2, as before
  DeltaDecoder dec(params);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  enc.Begin(buf, 7);
  EntityState s;
  s.entity_id = 4;
  s.position = {1, 2, 3};
  const EntityVelocity v{{1, 0, 0}, {0, 0, 0}};
  ASSERT_TRUE(enc.Add(s, nullptr, &v));  // ignored without the option
  const size_t size = enc.Finish();
  ASSERT_EQ(buf[0], kDeltaStateFormat);
  StateBatch batch;
  ASSERT_TRUE(dec.Decode({buf.data(), size}, &batch).ok());
  ASSERT_EQ(batch.states.size(), 1u);
  EXPECT_TRUE(batch.velocities.empty());
}

TEST(ExtrapolateState, MovesLinearlyTurnsAboutTheWorldAxisAndHoldsAtTheLimit) {
  EntityState s;
  s.position = {1, 2, 3};
  s.rotation = {0, 0, 0, 1};
  const EntityVelocity v{{2, 0, -1}, {0, 0, 1}};  // 1 rad/s about +z
  const EntityState a = ExtrapolateState(s, v, 0.5);
  EXPECT_NEAR(a.position.x, 2.0, 1e-6);
  EXPECT_NEAR(a.position.z, 2.5, 1e-6);
  EXPECT_NEAR(a.rotation.z, std::sin(0.25), 1e-6);
  EXPECT_NEAR(a.rotation.w, std::cos(0.25), 1e-6);
  const EntityState limit = ExtrapolateState(s, v, kVelocityExtrapolationLimitS);
  const EntityState beyond = ExtrapolateState(s, v, 30.0);
  EXPECT_EQ(beyond.position.x, limit.position.x);
  EXPECT_EQ(beyond.rotation.z, limit.rotation.z);
  const EntityState back = ExtrapolateState(s, v, -1.0);  // never into the past
  EXPECT_EQ(back.position.x, s.position.x);
  EXPECT_EQ(ExtrapolateState(s, v, std::nan("")).position.x, s.position.x);
}

TEST(HermitePosition, ExactForConstantAcceleration) {
  // x(t) = 1 + 2 t - 3 t^2 over [0, 0.4]: v(t) = 2 - 6 t.
  const double h = 0.4;
  auto x = [](double t) { return static_cast<float>(1 + 2 * t - 3 * t * t); };
  auto v = [](double t) { return static_cast<float>(2 - 6 * t); };
  for (double tau : {0.0, 0.1, 0.5, 0.77, 1.0}) {
    const Vec3f p = HermitePosition({x(0), 0, 0}, {v(0), 0, 0}, {x(h), 5, 0}, {v(h), 0, 0}, h, tau);
    EXPECT_NEAR(p.x, x(tau * h), 1e-6) << tau;
  }
}

class NeedExtrapolatedTest : public ::testing::Test {
 protected:
  // Sends entity 1 at `pos` with velocity `v` in a payload at `time_ms`, acknowledged.
  void SendAcked(const Vec3f& pos, const EntityVelocity& v, uint32_t time_ms) {
    EntityState s;
    s.entity_id = 1;
    s.position = pos;
    enc.Begin(buf, time_ms);
    ASSERT_TRUE(enc.Add(s, nullptr, &v));
    ASSERT_GT(enc.Finish(), 0u);
    enc.OnSent(seq, time_ms / 1000.0);
    enc.OnPacketAcked(seq++);
  }
  DeltaEncoder::UpdateNeed At(const Vec3f& truth_pos, uint32_t time_ms, const Quatf& rot = {}) {
    EntityState truth;
    truth.entity_id = 1;
    truth.position = truth_pos;
    truth.rotation = rot;
    return enc.NeedExtrapolated(1, truth, 0.005f, 2.0f, time_ms / 1000.0, 0.1, time_ms);
  }
  QuantizationParams params = Params();
  DeltaEncoder enc{params, WithVelocities()};
  std::vector<uint8_t> buf = std::vector<uint8_t>(kMaxUnreliablePayload);
  uint16_t seq = 0;
};

TEST_F(NeedExtrapolatedTest, SendsOnlyWhenTheReceiversExtrapolationStrays) {
  using N = DeltaEncoder::UpdateNeed;
  EXPECT_EQ(At({0, 0, 0}, 0), N::kSend);  // never sent
  SendAcked({0, 1, 0}, {{1, 0, 0}, {}}, 1000);
  EXPECT_EQ(At({0.1f, 1, 0}, 1100), N::kExtrapolatedWithin);  // on the extrapolated line
  EXPECT_EQ(At({0.104f, 1, 0}, 1100), N::kExtrapolatedWithin);
  EXPECT_EQ(At({0.107f, 1, 0}, 1100), N::kSend);  // 7 mm off
  EXPECT_EQ(At({0.0f, 1, 0}, 1100), N::kSend);    // it stopped: the receiver's copy runs on
  // Beyond the limit the receiver holds the pose extrapolated to the limit.
  EXPECT_EQ(At({1.0f, 1, 0}, 1000 + 5000), N::kExtrapolatedWithin);
  EXPECT_EQ(At({1.5f, 1, 0}, 1000 + 1500), N::kSend);
  // Turning at 1 rad/s about z: after 0.5 s the receiver shows 0.5 rad.
  SendAcked({0, 1, 0}, {{}, {0, 0, 1}}, 3000);
  const Quatf turned{0, 0, static_cast<float>(std::sin(0.25)), static_cast<float>(std::cos(0.25))};
  EXPECT_EQ(At({0, 1, 0}, 3500, turned), N::kExtrapolatedWithin);
  EXPECT_EQ(At({0, 1, 0}, 3500), N::kSend);  // did not turn: 28.6 deg off
  // At rest: as Need, whose "within" is sticky.
  SendAcked({0, 1, 0}, {}, 4000);
  EXPECT_EQ(At({0.002f, 1, 0}, 4500), N::kAckedWithin);
  EXPECT_EQ(At({0.02f, 1, 0}, 4500), N::kSend);
}

TEST_F(NeedExtrapolatedTest, AStateInFlightCountsUntilTheResendTime) {
  using N = DeltaEncoder::UpdateNeed;
  EntityState s;
  s.entity_id = 1;
  enc.Begin(buf, 0);
  const EntityVelocity v{{1, 0, 0}, {}};
  ASSERT_TRUE(enc.Add(s, nullptr, &v));
  ASSERT_GT(enc.Finish(), 0u);
  enc.OnSent(seq++, 0.0);  // never acknowledged
  EXPECT_EQ(At({0.05f, 0, 0}, 50), N::kInFlightWithin);
  EXPECT_EQ(At({0.0f, 0, 0}, 50), N::kSend);
  EXPECT_EQ(At({0.2f, 0, 0}, 200), N::kSend);  // past resend_after (0.1 s)
  EntityState held;
  EntityVelocity held_v;
  uint32_t held_ms = 1;
  ASSERT_TRUE(enc.NewestSent(1, &held, &held_v, &held_ms));
  EXPECT_EQ(held_ms, 0u);
  EXPECT_FLOAT_EQ(held_v.linear.x, 1.0f);
  EXPECT_FALSE(enc.NewestSent(2, &held, &held_v, &held_ms));
}

}  // namespace
}  // namespace edgephys
