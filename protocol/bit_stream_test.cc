#include "protocol/bit_stream.h"

#include <gtest/gtest.h>

#include <random>
#include <vector>

namespace edgephys {
namespace {

TEST(BitStream, ZigZagRoundTrips) {
  for (int32_t v : {0, -1, 1, -2, 2, 1000, -1000, INT32_MAX, INT32_MIN}) {
    EXPECT_EQ(UnZigZag(ZigZag(v)), v);
  }
  EXPECT_EQ(ZigZag(0), 0u);
  EXPECT_EQ(ZigZag(-1), 1u);
  EXPECT_EQ(ZigZag(1), 2u);
  EXPECT_EQ(ZigZag(INT32_MIN), UINT32_MAX);
}

TEST(BitStream, MixedFieldsRoundTripAndPadWithZeros) {
  std::mt19937_64 rng(1);
  for (int round = 0; round < 200; ++round) {
    std::vector<uint8_t> buf(2048, 0xAB);
    BitWriter w(buf);
    struct Field {
      int kind, bits, k;
      uint64_t value;
    };
    std::vector<Field> fields;
    for (int i = 0; i < 100; ++i) {
      Field f{static_cast<int>(rng() % 3), static_cast<int>(rng() % 65),
              static_cast<int>(rng() % 8), rng()};
      if (f.kind == 0) {
        if (f.bits < 64) f.value &= (uint64_t{1} << f.bits) - 1;
        ASSERT_TRUE(w.WriteBits(f.value, f.bits));
      } else if (f.kind == 1) {
        f.value = static_cast<uint32_t>(f.value >> (rng() % 33));
        ASSERT_TRUE(w.WriteExpGolomb(static_cast<uint32_t>(f.value), f.k));
      } else {
        f.value = static_cast<uint64_t>(static_cast<int64_t>(static_cast<int32_t>(f.value)) >>
                                        (rng() % 32));
        ASSERT_TRUE(w.WriteSigned(static_cast<int32_t>(f.value), f.k));
      }
      fields.push_back(f);
    }
    const size_t bits = w.bit_position();
    if (bits % 8) {
      EXPECT_EQ(buf[bits / 8] >> (bits % 8), 0);  // zero padding
    }
    BitReader r(std::span<const uint8_t>(buf.data(), w.byte_size()));
    for (const Field& f : fields) {
      if (f.kind == 0) {
        uint64_t v;
        ASSERT_TRUE(r.ReadBits(f.bits, &v));
        ASSERT_EQ(v, f.value);
      } else if (f.kind == 1) {
        uint32_t v;
        ASSERT_TRUE(r.ReadExpGolomb(f.k, &v));
        ASSERT_EQ(v, f.value);
      } else {
        int32_t v;
        ASSERT_TRUE(r.ReadSigned(f.k, &v));
        ASSERT_EQ(v, static_cast<int32_t>(f.value));
      }
    }
    EXPECT_LT(r.remaining_bits(), 8u);
  }
}

TEST(BitStream, ExpGolombLengthsMatchTheFormula) {
  std::vector<uint8_t> buf(16);
  for (int k = 0; k < 8; ++k) {
    for (uint32_t u : {0u, 1u, 2u, 3u, 7u, 100u, 65535u, UINT32_MAX}) {
      BitWriter w(buf);
      ASSERT_TRUE(w.WriteExpGolomb(u, k));
      EXPECT_EQ(static_cast<int>(w.bit_position()), ExpGolombBits(u, k));
    }
  }
  EXPECT_EQ(ExpGolombBits(0, 0), 1);
  EXPECT_EQ(ExpGolombBits(1, 0), 3);
  EXPECT_EQ(ExpGolombBits(0, 2), 3);
}

TEST(BitStream, WriterNeverOverrunsAndRewinds) {
  std::vector<uint8_t> storage(8, 0xEE);
  std::span<uint8_t> buf(storage.data() + 2, 4);  // guard bytes around
  BitWriter w(buf);
  EXPECT_TRUE(w.WriteBits(0x1FFFFFF, 25));
  const size_t mark = w.bit_position();
  EXPECT_FALSE(w.WriteBits(0xFF, 8));  // 33 > 32 bits
  EXPECT_TRUE(w.overflow());
  EXPECT_EQ(w.bit_position(), mark);
  EXPECT_FALSE(w.WriteExpGolomb(1000, 0));
  EXPECT_TRUE(w.WriteBits(3, 2));
  w.Rewind(mark);
  EXPECT_FALSE(w.overflow());
  EXPECT_EQ(buf[3], 0x01);  // bits above the mark cleared
  EXPECT_TRUE(w.WriteBits(0x7F, 7));
  EXPECT_EQ(storage[0], 0xEE);
  EXPECT_EQ(storage[1], 0xEE);
  EXPECT_EQ(storage[6], 0xEE);
  EXPECT_EQ(storage[7], 0xEE);
}

TEST(BitStream, ReaderRejectsOverrunsAndOverlongCodes) {
  const uint8_t data[2] = {0x00, 0x00};
  BitReader r(data);
  uint64_t v;
  EXPECT_FALSE(r.ReadBits(17, &v));
  EXPECT_EQ(r.bit_position(), 0u);
  uint32_t u;
  EXPECT_FALSE(r.ReadExpGolomb(0, &u));  // all zeros: prefix never terminates
  EXPECT_EQ(r.bit_position(), 0u);
  const uint8_t long_prefix[6] = {0, 0, 0, 0, 0x02, 0};  // 33 zero bits then a 1
  BitReader r2(long_prefix);
  EXPECT_FALSE(r2.ReadExpGolomb(0, &u));
  std::mt19937_64 rng(2);
  for (int i = 0; i < 20000; ++i) {
    std::vector<uint8_t> junk(rng() % 12);
    for (auto& b : junk) b = static_cast<uint8_t>(rng());
    BitReader rr(junk);
    int32_t s;
    while (rr.ReadSigned(static_cast<int>(rng() % 8), &s)) {
    }
    EXPECT_LE(rr.bit_position(), junk.size() * 8);
  }
}

}  // namespace
}  // namespace edgephys
