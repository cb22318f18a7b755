// The binary range coder of format 11: round trips of adaptive and direct bits, compression of
// skewed decisions, and arbitrary input decoding without touching memory outside the span.
#include "protocol/range_coder.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace edgephys {
namespace {

TEST(RangeCoder, RoundTripsMixedAdaptiveAndDirectBits) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const size_t n = 1 + rng() % 5000;
    const double p_one = std::uniform_real_distribution<double>(0, 1)(rng);
    std::vector<int> bits(n), kinds(n);
    for (size_t i = 0; i < n; ++i) {
      bits[i] = std::bernoulli_distribution(p_one)(rng) ? 1 : 0;
      kinds[i] = static_cast<int>(rng() % 4);  // 0..2: one of three cells, 3: direct
    }
    std::vector<uint8_t> buf(n / 4 + 64);
    RangeEncoder enc(buf);
    RangeProb cells[3] = {kRangeProbInit, kRangeProbInit, kRangeProbInit};
    for (size_t i = 0; i < n; ++i) {
      if (kinds[i] == 3) {
        enc.EncodeDirect(bits[i] != 0);
      } else {
        enc.EncodeBit(&cells[kinds[i]], bits[i] != 0);
      }
    }
    const size_t size = enc.Finish();
    ASSERT_FALSE(enc.overflow());
    RangeDecoder dec(std::span<const uint8_t>(buf.data(), size));
    RangeProb dcells[3] = {kRangeProbInit, kRangeProbInit, kRangeProbInit};
    for (size_t i = 0; i < n; ++i) {
      const bool bit = kinds[i] == 3 ? dec.DecodeDirect() : dec.DecodeBit(&dcells[kinds[i]]);
      ASSERT_EQ(bit, bits[i] != 0) << "trial " << trial << " bit " << i;
    }
  }
}

TEST(RangeCoder, SkewedDecisionsCostAFractionOfABit) {
  std::vector<uint8_t> buf(256);
  RangeEncoder enc(buf);
  RangeProb cell = kRangeProbInit;
  for (int i = 0; i < 4000; ++i) enc.EncodeBit(&cell, false);
  const size_t size = enc.Finish();
  EXPECT_LE(size, 12u);  // 4000 near-certain decisions: well under 0.03 bit each
}

TEST(RangeCoder, OverflowIsReportedNotWritten) {
  std::vector<uint8_t> buf(8, 0xAA);
  RangeEncoder enc(std::span<uint8_t>(buf.data(), 4));
  for (int i = 0; i < 200; ++i) enc.EncodeDirect(i % 3 == 0);
  EXPECT_EQ(enc.Finish(), 0u);
  EXPECT_TRUE(enc.overflow());
  for (size_t i = 4; i < buf.size(); ++i) EXPECT_EQ(buf[i], 0xAA);
}

TEST(RangeCoder, ArbitraryInputDecodesWithinBounds) {
  std::mt19937 rng(3);
  for (int trial = 0; trial < 200; ++trial) {
    std::vector<uint8_t> in(rng() % 16);
    for (auto& b : in) b = static_cast<uint8_t>(rng());
    RangeDecoder dec(in);
    RangeProb cell = kRangeProbInit;
    for (int i = 0; i < 500; ++i) (void)(i % 2 ? dec.DecodeDirect() : dec.DecodeBit(&cell));
    EXPECT_GE(cell, 1u);
    EXPECT_LT(cell, 1u << kRangeProbBits);
  }
}

}  // namespace
}  // namespace edgephys
