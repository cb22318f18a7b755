#include "protocol/quantize.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "protocol/testing/codec_test_util.h"

namespace edgephys {
namespace {

using namespace testing_util;  // NOLINT(google-build-using-namespace): test helpers

QuantizationConfig Config(float step, float rot_deg, float extent) {
  QuantizationConfig c;
  c.bounds_min = {-extent, -extent * 0.5f, -extent};
  c.bounds_max = {extent, extent * 0.5f, extent};
  c.position_step_m = step;
  c.rotation_error_deg = rot_deg;
  return c;
}

TEST(Quantize, DefaultParamsMatchTheDocumentedMaths) {
  auto p = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(p.ok());
  // theta ~ sqrt(6) / M, slightly more (stretch near w = 1/2).
  EXPECT_GE(p->rotation_max, 1404);
  EXPECT_LE(p->rotation_max, 1410);
  EXPECT_EQ(p->rotation_bits, 12);
  EXPECT_LE(RotationErrorBoundRad(p->rotation_max), 0.1 * M_PI / 180.0);
  EXPECT_GT(RotationErrorBoundRad(p->rotation_max - 1), 0.1 * M_PI / 180.0 * (1 - 1e-4));
  EXPECT_EQ(p->max_index[0], 2000000u);
  EXPECT_EQ(p->position_bits[0], 21);
  std::printf("default rotation M = %d, %d bits/component\n", p->rotation_max, p->rotation_bits);
}

TEST(Quantize, RejectsBadConfigs) {
  QuantizationConfig c;
  c.position_step_m = 0;
  EXPECT_FALSE(MakeQuantizationParams(c).ok());
  c = {};
  c.bounds_max.x = c.bounds_min.x;
  EXPECT_FALSE(MakeQuantizationParams(c).ok());
  c = {};
  c.position_step_m = 1e-7f;  // 2e10 lattice points per axis
  EXPECT_FALSE(MakeQuantizationParams(c).ok());
  c = {};
  c.rotation_error_deg = 0;
  EXPECT_FALSE(MakeQuantizationParams(c).ok());
  c.rotation_error_deg = NAN;
  EXPECT_FALSE(MakeQuantizationParams(c).ok());
}

TEST(Quantize, RandomTransformsStayWithinBoundsForSeveralConfigs) {
  const QuantizationConfig configs[] = {Config(0.001f, 0.1f, 500.f), Config(0.0005f, 0.05f, 50.f),
                                        Config(0.01f, 1.0f, 1000.f), Config(0.002f, 0.02f, 8.f),
                                        Config(0.001f, 0.001f, 100.f)};
  std::mt19937_64 rng(3);
  for (const QuantizationConfig& c : configs) {
    auto p = MakeQuantizationParams(c);
    ASSERT_TRUE(p.ok());
    std::uniform_real_distribution<float> ux(c.bounds_min.x, c.bounds_max.x);
    std::uniform_real_distribution<float> uy(c.bounds_min.y, c.bounds_max.y);
    double worst_pos = 0, worst_rot = 0;
    for (int i = 0; i < 200000; ++i) {
      EntityState s;
      s.position = {ux(rng), uy(rng), ux(rng)};
      s.rotation = RandomRotation(rng);
      if (i % 1000 == 0) s.rotation = {0.5f, 0.5f, 0.5f, -0.5f};  // worst case for the code
      QuantizedState q;
      ASSERT_TRUE(QuantizeState(*p, s, &q));
      const Vec3f pos = DequantizePosition(*p, q.position);
      const Quatf rot = DequantizeRotation(*p, q.rotation);
      const double pe = PositionError(pos, s.position);
      const double re = RotationErrorDeg(rot, s.rotation);
      worst_pos = std::max(worst_pos, pe);
      worst_rot = std::max(worst_rot, re);
      ASSERT_LE(pe, c.position_step_m * std::sqrt(3.0) / 2 + FloatSlack(c.bounds_max.x));
      ASSERT_LE(re, c.rotation_error_deg);
      // Sign canonicalisation: the dropped component is non-negative.
      const float comps[4] = {rot.x, rot.y, rot.z, rot.w};
      ASSERT_GE(comps[q.rotation.largest], 0.f);
    }
    std::printf("step %g bound %g deg: worst pos %.4g m, worst rot %.4g deg\n", c.position_step_m,
                c.rotation_error_deg, worst_pos, worst_rot);
  }
}

TEST(Quantize, WorstCaseRotationDirectionStaysWithinBound) {
  // Error pushing |v| outward at the point where all four components are equal.
  auto p = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(p.ok());
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> jitter(-0.02, 0.02);
  double worst = 0;
  for (int i = 0; i < 200000; ++i) {
    double q[4] = {0.5 + jitter(rng), 0.5 + jitter(rng), 0.5 + jitter(rng), 0.5 + jitter(rng)};
    double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
    Quatf r{static_cast<float>(q[0] / n), static_cast<float>(q[1] / n),
            static_cast<float>(q[2] / n), static_cast<float>(q[3] / n)};
    QuantizedRotation qr;
    ASSERT_TRUE(QuantizeRotation(*p, r, &qr));
    worst = std::max(worst, RotationErrorDeg(DequantizeRotation(*p, qr), r));
  }
  EXPECT_LE(worst, 0.1);
  std::printf("worst rotation error near the w = 1/2 corner: %.5f deg\n", worst);
}

TEST(Quantize, OutOfBoundsIsClampedAndReported) {
  auto p = MakeQuantizationParams(Config(0.001f, 0.1f, 10.f));
  ASSERT_TRUE(p.ok());
  std::array<uint32_t, 3> q;
  EXPECT_TRUE(QuantizePosition(*p, {1.f, 2.f, 3.f}, &q));
  EXPECT_FALSE(QuantizePosition(*p, {11.f, 0.f, 0.f}, &q));
  EXPECT_EQ(q[0], p->max_index[0]);
  EXPECT_FALSE(QuantizePosition(*p, {0.f, -6.f, 0.f}, &q));
  EXPECT_EQ(q[1], 0u);
  EXPECT_FALSE(QuantizePosition(*p, {NAN, 0.f, INFINITY}, &q));
  EXPECT_LE(q[0], p->max_index[0]);
  EXPECT_LE(q[2], p->max_index[2]);
  QuantizedRotation r;
  EXPECT_FALSE(QuantizeRotation(*p, {NAN, 0, 0, 1}, &r));
  EXPECT_FALSE(QuantizeRotation(*p, {0, 0, 0, 0}, &r));
  EXPECT_LT(RotationErrorDeg(DequantizeRotation(*p, r), Quatf{}), 0.1);
  // Non-unit input is normalised.
  EXPECT_TRUE(QuantizeRotation(*p, {0, 0, 0, 2}, &r));
  EXPECT_LT(RotationErrorDeg(DequantizeRotation(*p, r), Quatf{}), 0.1);
}

TEST(Quantize, SignOfTheQuaternionDoesNotMatter) {
  auto p = MakeQuantizationParams(QuantizationConfig{});
  ASSERT_TRUE(p.ok());
  std::mt19937_64 rng(9);
  for (int i = 0; i < 10000; ++i) {
    Quatf r = RandomRotation(rng);
    QuantizedRotation a, b;
    QuantizeRotation(*p, r, &a);
    QuantizeRotation(*p, {-r.x, -r.y, -r.z, -r.w}, &b);
    ASSERT_EQ(a, b);
  }
}

TEST(Quantize, IntegerSqrtAndInt4AreExact) {
  for (int64_t v : {0LL, 1LL, 2LL, 3LL, 4LL, 15LL, 16LL, 17LL, 999999999999LL, (1LL << 62) - 1}) {
    const int64_t r = IntegerSqrt(v);
    EXPECT_LE(r * r, v);
    EXPECT_GT((r + 1) * (r + 1), v);
  }
  auto p = MakeQuantizationParams(QuantizationConfig{});
  QuantizedRotation r;
  QuantizeRotation(*p, Quatf{}, &r);
  auto v = RotationToInt4(*p, r);
  EXPECT_EQ(v[0], 0);
  EXPECT_EQ(v[3], IntegerSqrt(2LL * p->rotation_max * p->rotation_max));
}

}  // namespace
}  // namespace edgephys
