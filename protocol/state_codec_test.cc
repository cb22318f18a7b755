#include "protocol/state_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "protocol/connection.h"

namespace edgephys {
namespace {

EntityState RandomState(std::mt19937_64& rng) {
  std::uniform_real_distribution<float> pos(-1000.f, 1000.f);
  std::normal_distribution<float> n(0.f, 1.f);
  float q[4] = {n(rng), n(rng), n(rng), n(rng)};
  float len = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  EntityState s;
  s.entity_id = static_cast<uint32_t>(rng());
  s.position = {pos(rng), pos(rng), pos(rng)};
  s.rotation = {q[0] / len, q[1] / len, q[2] / len, q[3] / len};
  return s;
}

TEST(StateCodec, RoundTripsRandomBatchesExactlyAndFillsTheMtu) {
  std::mt19937_64 rng(7);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  FloatStateEncoder enc;
  StateBatch batch;
  for (int round = 0; round < 500; ++round) {
    enc.Begin(buf, static_cast<uint32_t>(round * 33));
    std::vector<EntityState> in;
    for (;;) {
      EntityState s = RandomState(rng);
      if (!enc.Add(s)) break;
      in.push_back(s);
    }
    size_t size = enc.Finish();
    ASSERT_LE(size, kMaxUnreliablePayload);
    // Full: no room for another entity of the largest size.
    EXPECT_GT(size + 5 + 28, kMaxUnreliablePayload - 5);
    ASSERT_TRUE(DecodeStateBatch({buf.data(), size}, &batch).ok());
    EXPECT_EQ(batch.time_ms, static_cast<uint32_t>(round * 33));
    ASSERT_EQ(batch.states.size(), in.size());
    for (size_t i = 0; i < in.size(); ++i) {
      EXPECT_EQ(batch.states[i].entity_id, in[i].entity_id);
      EXPECT_EQ(batch.states[i].position.x, in[i].position.x);
      EXPECT_EQ(batch.states[i].position.y, in[i].position.y);
      EXPECT_EQ(batch.states[i].position.z, in[i].position.z);
      EXPECT_EQ(batch.states[i].rotation.w, in[i].rotation.w);
      EXPECT_TRUE(IsValidState(batch.states[i]));
    }
  }
}

TEST(StateCodec, MalformedPayloadsAreRejectedNeverCrash) {
  std::mt19937_64 rng(11);
  std::vector<uint8_t> buf(256);
  FloatStateEncoder enc;
  enc.Begin(buf, 5);
  for (int i = 0; i < 5; ++i) enc.Add(RandomState(rng));
  size_t size = enc.Finish();
  StateBatch batch;
  std::span<const uint8_t> good(buf.data(), size);
  ASSERT_TRUE(DecodeStateBatch(good, &batch).ok());
  for (size_t n = 0; n < size; ++n) EXPECT_FALSE(DecodeStateBatch(good.first(n), &batch).ok());
  std::vector<uint8_t> longer(good.begin(), good.end());
  longer.push_back(0);
  EXPECT_FALSE(DecodeStateBatch(longer, &batch).ok());
  std::vector<uint8_t> wrong_format(good.begin(), good.end());
  wrong_format[0] = 99;
  EXPECT_FALSE(DecodeStateBatch(wrong_format, &batch).ok());
  for (int i = 0; i < 20000; ++i) {
    std::vector<uint8_t> p(rng() % 300);
    for (auto& b : p) b = static_cast<uint8_t>(rng());
    if (!p.empty() && rng() % 2) p[0] = 1;
    (void)DecodeStateBatch(p, &batch);  // must not crash or over-read (ASan/UBSan builds)
  }
  std::vector<uint8_t> huge_count = {1, 0, 0, 0, 0, 0xff, 0xff, 0xff, 0xff, 0x0f};
  EXPECT_FALSE(DecodeStateBatch(huge_count, &batch).ok());
}

TEST(StateCodec, ValidityRejectsNanInfiniteFarAndNonUnit) {
  EntityState s;
  EXPECT_TRUE(IsValidState(s));
  s.position.x = std::nanf("");
  EXPECT_FALSE(IsValidState(s));
  s.position.x = INFINITY;
  EXPECT_FALSE(IsValidState(s));
  s.position.x = 2e6f;
  EXPECT_FALSE(IsValidState(s));
  s.position.x = 0;
  s.rotation = {0, 0, 0, 0};
  EXPECT_FALSE(IsValidState(s));
  s.rotation = {0, 0, 0.70710678f, 0.70710678f};
  EXPECT_TRUE(IsValidState(s));
}

TEST(StateCodec, VarintRoundTripAndBounds) {
  uint8_t b[5];
  for (uint32_t v : {0u, 1u, 127u, 128u, 16383u, 16384u, 0xffffffffu}) {
    size_t n = PutVarint32(v, b);
    ASSERT_GT(n, 0u);
    uint32_t back = 0;
    EXPECT_EQ(GetVarint32({b, n}, &back), n);
    EXPECT_EQ(back, v);
    EXPECT_EQ(GetVarint32({b, n - 1}, &back), 0u);
  }
  EXPECT_EQ(PutVarint32(300, std::span<uint8_t>(b, 1)), 0u);
  const uint8_t overflow[] = {0xff, 0xff, 0xff, 0xff, 0x7f};
  uint32_t v;
  EXPECT_EQ(GetVarint32(overflow, &v), 0u);
}

}  // namespace
}  // namespace edgephys
