// Format-2 streams end to end: random transforms, loss, reordering, stale-dropping
// transports and the acceptance motion, through the stream simulator.
#include <gtest/gtest.h>

#include <random>
#include <vector>

#include "protocol/delta_codec.h"
#include "protocol/testing/codec_test_util.h"
#include "protocol/testing/delta_stream_sim.h"

namespace edgephys {
namespace {

using namespace testing_util;  // NOLINT(google-build-using-namespace): test helpers

TEST(DeltaCodec, RandomTransformsRoundTripWithinBoundsForSeveralConfigs) {
  std::mt19937_64 rng(17);
  const float steps[] = {0.001f, 0.0002f, 0.005f};
  const float bounds[] = {0.1f, 0.02f, 1.0f};
  for (int ci = 0; ci < 3; ++ci) {
    QuantizationConfig qc;
    qc.bounds_min = {-50, -5, -50};
    qc.bounds_max = {50, 20, 50};
    qc.position_step_m = steps[ci];
    qc.rotation_error_deg = bounds[ci];
    auto params = MakeQuantizationParams(qc);
    ASSERT_TRUE(params.ok());
    DeltaEncoder enc(*params);
    DeltaDecoder dec(*params);
    std::vector<uint8_t> buf(kMaxUnreliablePayload);
    std::uniform_real_distribution<float> ux(-50, 50), uy(-5, 20), small(-0.3f, 0.3f);
    std::vector<EntityState> state(40);
    for (size_t i = 0; i < state.size(); ++i) {
      state[i].entity_id = static_cast<uint32_t>(i * 7);
      state[i].position = {ux(rng), uy(rng), ux(rng)};
      state[i].rotation = RandomRotation(rng);
    }
    StateBatch batch;
    uint16_t seq = 0;
    for (int round = 0; round < 400; ++round) {
      for (auto& s : state) {
        // Mix of random jumps and small moves.
        if (rng() % 4 == 0) {
          s.position = {ux(rng), uy(rng), ux(rng)};
          s.rotation = RandomRotation(rng);
        } else {
          s.position.x = std::clamp(s.position.x + small(rng), -50.f, 50.f);
          s.position.y = std::clamp(s.position.y + small(rng), -5.f, 20.f);
        }
      }
      enc.Begin(buf, static_cast<uint32_t>(round * 20));
      size_t added = 0;
      for (const auto& s : state) added += enc.Add(s) ? 1 : 0;
      ASSERT_EQ(added, state.size());
      const size_t size = enc.Finish();
      enc.OnSent(seq, round * 0.02);
      batch.states.clear();
      ASSERT_TRUE(dec.Decode({buf.data(), size}, &batch).ok());
      ASSERT_EQ(batch.states.size(), state.size());
      for (size_t i = 0; i < state.size(); ++i) {
        ASSERT_EQ(batch.states[i].entity_id, state[i].entity_id);
        ASSERT_LE(PositionError(batch.states[i].position, state[i].position),
                  qc.position_step_m * std::sqrt(3.0) / 2 + FloatSlack(60));
        ASSERT_LE(RotationErrorDeg(batch.states[i].rotation, state[i].rotation),
                  qc.rotation_error_deg);
      }
      if (rng() % 5 != 0) enc.OnPacketAcked(seq);  // some acks never come
      ++seq;
    }
    EXPECT_EQ(dec.stats().unresolved_references, 0u);
    EXPECT_GT(enc.stats().keyframes, state.size());
    EXPECT_LT(enc.stats().keyframes, enc.stats().entities);
  }
}

TEST(DeltaCodec, LossyReorderedStreamConvergesWithinBoundsAndOnlyReferencesAckedStates) {
  for (uint64_t seed : {1, 2, 3}) {
    SimConfig c = LossyReorderedSim(seed);
    c.quant.position_step_m = seed == 2 ? 0.0005f : 0.001f;
    c.quant.rotation_error_deg = seed == 3 ? 0.05f : 0.1f;
    SimResult r = RunStream(c);
    ExpectConvergedUnderLoss(r, c.quant, seed);
  }
}

TEST(DeltaCodec, StaleDroppingTransportNeverYieldsGarbageAndRefreshRecovers) {
  // Connection's sequenced channel acks payloads it then drops as stale: the worst case for
  // delta coding. Entities may be skipped, never decoded wrongly, and keyframe refresh heals.
  SimConfig c;
  c.entities = 400;  // several payloads per tick: entities differ between payloads
  c.ticks = 500;
  c.tick_hz = 48;
  c.loss = 0.1;
  c.max_extra_delay_ticks = 2;
  c.ack_delay_ticks = 1;
  c.drop_stale = true;
  c.check_references = false;
  c.options.keyframe_refresh_sends = 48;
  c.freeze_after_tick = 380;
  c.lossless_after_tick = 380;
  SimResult r = RunStream(c);
  std::printf("stale-dropping transport: unresolved %llu of %llu records, %.2f bytes/update\n",
              static_cast<unsigned long long>(r.dec.unresolved_references),
              static_cast<unsigned long long>(r.updates), r.BytesPerUpdate());
  ExpectWithinBounds(r, c.quant);
  EXPECT_GT(r.dec.unresolved_references, 0u);
  EXPECT_TRUE(r.converged);
}

TEST(DeltaCodec, AcceptanceMotionBytesPerUpdateAndErrors) {
  struct Case {
    int n;
    double loss;
  };
  const Case cases[] = {{32, 0}, {128, 0}, {512, 0}, {32, 0.05}, {128, 0.05}, {512, 0.05}};
  for (const Case& cs : cases) {
    for (int family : {0, 1}) {
      for (uint64_t seed : {11, 12}) {
        SimConfig c;
        c.entities = cs.n;
        c.ticks = 12 * 20;
        c.tick_hz = 12;
        c.loss = cs.loss;
        c.ack_delay_ticks = 1;
        c.family = family;
        c.seed = seed;
        SimResult r = RunStream(c);
        std::printf(
            "ACCEPTANCE N=%3d loss=%.2f motion=%s seed=%llu: %.3f bytes/update (%llu packets), "
            "max err %.3f mm %.4f deg, keyframes %llu, residual bits EG %llu vs fixed-width "
            "%llu\n",
            cs.n, cs.loss, family == 0 ? "wander" : "lissajous",
            static_cast<unsigned long long>(seed), r.BytesPerUpdate(),
            static_cast<unsigned long long>(r.packets), r.max_pos_err * 1e3, r.max_rot_err,
            static_cast<unsigned long long>(r.enc.keyframes),
            static_cast<unsigned long long>(r.enc.residual_bits_exp_golomb),
            static_cast<unsigned long long>(r.enc.residual_bits_fixed_width));
        EXPECT_LE(r.BytesPerUpdate(), 7.0);
        ExpectWithinBounds(r, c.quant);
        EXPECT_EQ(r.bad_references, 0u);
        EXPECT_EQ(r.dec.unresolved_references, 0u);
      }
    }
  }
}

TEST(DeltaCodec, OtherSpeedsAndSpinsStayWithinBounds) {
  for (double speed : {0.0, 0.3, 4.0}) {
    for (double spin : {0.0, 30.0, 360.0}) {
      SimConfig c;
      c.entities = 64;
      c.ticks = 120;
      c.loss = 0.05;
      c.speed = speed;
      c.spin_dps = spin;
      c.family = -1;
      SimResult r = RunStream(c);
      std::printf("speed %.1f m/s spin %3.0f deg/s: %.3f bytes/update, %.3f mm %.4f deg\n", speed,
                  spin, r.BytesPerUpdate(), r.max_pos_err * 1e3, r.max_rot_err);
      ExpectWithinBounds(r, c.quant);
      EXPECT_EQ(r.dec.unresolved_references, 0u);
    }
  }
}

}  // namespace
}  // namespace edgephys
