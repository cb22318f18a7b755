// Format 11 records: round trips over many random bodies and motions (keyframe, baseline,
// extrapolation; within the lattice bound), chunking, the cost of a body at rest, and malformed
// records.
#include "protocol/soft_delta_codec.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "protocol/byte_io.h"
#include "protocol/connection.h"
#include "protocol/state_codec.h"

namespace edgephys {
namespace {

constexpr float kStep = 0.001f;

struct Body {
  std::vector<float> p;  // 3 x n, metres
  std::vector<int32_t> q;
  void Quantise() {
    q.resize(p.size());
    for (size_t i = 0; i < p.size(); ++i) q[i] = SoftLattice(p[i], kStep);
  }
};

// A lumpy body: particles on a jittered grid around `centre` (neighbours are close).
Body RandomBody(std::mt19937& rng, size_t n) {
  Body b;
  std::uniform_real_distribution<float> c(-20, 20), jitter(-0.004f, 0.004f);
  const float cx = c(rng), cy = c(rng), cz = c(rng);
  const size_t side = static_cast<size_t>(std::ceil(std::cbrt(static_cast<double>(n))));
  for (size_t i = 0; i < n; ++i) {
    b.p.push_back(cx + 0.02f * static_cast<float>(i % side) + jitter(rng));
    b.p.push_back(cy + 0.02f * static_cast<float>((i / side) % side) + jitter(rng));
    b.p.push_back(cz + 0.02f * static_cast<float>(i / (side * side)) + jitter(rng));
  }
  b.Quantise();
  return b;
}

// Moves `b` by a common translation plus a smooth local bulge plus small noise.
Body Move(const Body& b, std::mt19937& rng, float scale) {
  Body m = b;
  std::uniform_real_distribution<float> u(-1, 1);
  const float tx = u(rng) * scale, ty = u(rng) * scale, tz = u(rng) * scale;
  const size_t bulge = rng() % (b.p.size() / 3);
  for (size_t i = 0; i < b.p.size() / 3; ++i) {
    const float d = std::fabs(static_cast<float>(i) - static_cast<float>(bulge));
    const float w = std::exp(-d / 20.0f) * scale;
    m.p[i * 3] += tx + 0.1f * u(rng) * scale;
    m.p[i * 3 + 1] += ty - w;
    m.p[i * 3 + 2] += tz;
  }
  m.Quantise();
  return m;
}

// Encodes all of `v` in records into payloads of `mtu` bytes and decodes them back.
struct RoundTrip {
  size_t bytes = 0;
  size_t records = 0;
  std::vector<uint8_t> modes;
};

RoundTrip EncodeDecode(const Body& v, const SoftDeltaRefs& refs, uint32_t version, size_t mtu,
                       std::vector<int32_t>* decoded) {
  RoundTrip rt;
  SoftDeltaScratch scratch;
  decoded->assign(v.q.size(), 0);
  const uint32_t total = static_cast<uint32_t>(v.q.size() / 3);
  uint32_t first = 0;
  while (first < total) {
    std::vector<uint8_t> payload(mtu);
    size_t pos = BeginSoftDeltaPayload(1000, payload);
    SoftDeltaRecordInput in{.entity_id = 42, .version = version, .age_ms = 0, .q = v.q,
                            .first = first, .max_count = total - first, .refs = refs};
    uint32_t count = 0;
    uint8_t mode = 0;
    const size_t n = EncodeSoftDeltaRecord(in, std::span<uint8_t>(payload).subspan(pos), &scratch,
                                           &count, &mode);
    EXPECT_GT(n, 0u);
    if (n == 0) return rt;
    pos += n;
    payload.resize(pos);
    rt.bytes += pos;
    ++rt.records;
    rt.modes.push_back(mode);
    size_t at = kSoftDeltaHeaderSize;
    SoftDeltaRecord r;
    EXPECT_TRUE(ParseSoftDeltaRecord(payload, 1000, 1 << 16, &at, &r).ok());
    EXPECT_EQ(at, payload.size());
    EXPECT_EQ(r.first, first);
    EXPECT_EQ(r.count, count);
    EXPECT_EQ(r.total, total);
    EXPECT_EQ(r.version, version);
    EXPECT_TRUE(DecodeSoftDeltaResiduals(r, refs, *decoded).ok());
    first += count;
  }
  return rt;
}

void ExpectWithinLattice(const Body& truth, const std::vector<int32_t>& decoded) {
  ASSERT_EQ(decoded.size(), truth.q.size());
  for (size_t i = 0; i < decoded.size(); ++i) {
    ASSERT_EQ(decoded[i], truth.q[i]) << "coordinate " << i;
    ASSERT_LE(std::fabs(decoded[i] * kStep - truth.p[i]), kStep * 0.5f + 1e-5f * std::fabs(truth.p[i]));
  }
}

TEST(SoftDeltaCodec, RoundTripsRandomBodiesAndMotionsWithinTheLatticeBound) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 60; ++trial) {
    const size_t n = 1 + rng() % 900;
    Body b2 = RandomBody(rng, n);
    const float scale = std::vector<float>{0.0f, 0.0005f, 0.003f, 0.02f, 0.3f}[trial % 5];
    Body b1 = Move(b2, rng, scale);
    Body v = Move(b1, rng, scale);
    std::vector<int32_t> decoded;
    // Keyframe.
    EncodeDecode(v, {}, 9, kMaxUnreliablePayload, &decoded);
    ExpectWithinLattice(v, decoded);
    // Against one baseline.
    SoftDeltaRefs one{.base = b1.q, .base_distance = 2};
    EncodeDecode(v, one, 9, kMaxUnreliablePayload, &decoded);
    ExpectWithinLattice(v, decoded);
    // Against two (extrapolation allowed).
    SoftDeltaRefs two{.base = b1.q, .base_distance = 2, .base2 = b2.q, .base2_distance = 3,
                      .dt_ms = 33, .base_dt_ms = 21};
    RoundTrip rt = EncodeDecode(v, two, 9, kMaxUnreliablePayload, &decoded);
    ExpectWithinLattice(v, decoded);
    // Small payloads force many chunks.
    rt = EncodeDecode(v, two, 9, 120, &decoded);
    ExpectWithinLattice(v, decoded);
    EXPECT_GE(rt.records, 1u);
  }
}

TEST(SoftDeltaCodec, ExtremeCoordinatesRoundTrip) {
  Body b;
  const float far = 1.0e6f;  // lattice limit is ~1,073 km at 1 mm
  for (float x : {far, -far, 0.0f, far, -far, 0.0005f}) {
    b.p.push_back(x);
    b.p.push_back(-x);
    b.p.push_back(x * 0.5f);
  }
  b.Quantise();
  Body base = b;
  for (auto& v : base.q) v = -v;
  std::vector<int32_t> decoded;
  EncodeDecode(b, {}, 1, 1100, &decoded);
  EXPECT_EQ(decoded, b.q);
  SoftDeltaRefs refs{.base = base.q, .base_distance = 1, .base2 = b.q, .base2_distance = 1,
                     .dt_ms = 60000, .base_dt_ms = 1};
  EncodeDecode(b, refs, 3, 1100, &decoded);
  EXPECT_EQ(decoded, b.q);
}

TEST(SoftDeltaCodec, BodyAtRestCostsAlmostNothing) {
  std::mt19937 rng(5);
  Body b = RandomBody(rng, 510);
  std::vector<int32_t> decoded;
  SoftDeltaRefs refs{.base = b.q, .base_distance = 1};
  RoundTrip rt = EncodeDecode(b, refs, 2, 1100, &decoded);
  ExpectWithinLattice(b, decoded);
  EXPECT_EQ(rt.records, 1u);
  EXPECT_LE(rt.bytes, 40u);  // header + ~10 bytes of residuals for 1,530 zeros
  // A keyframe of the same body needs far more.
  RoundTrip key = EncodeDecode(b, {}, 2, 1100, &decoded);
  EXPECT_GT(key.bytes, 20 * rt.bytes);
}

TEST(SoftDeltaCodec, SmoothMotionIsCheaperWithExtrapolation) {
  std::mt19937 rng(9);
  Body b2 = RandomBody(rng, 510);
  Body b1 = b2, v = b2;
  std::uniform_real_distribution<float> speed(0.005f, 0.03f);
  for (size_t i = 0; i < b2.p.size(); i += 3) {  // constant velocity, unrelated per particle
    const float vel = speed(rng);
    b1.p[i + 1] += vel;
    v.p[i + 1] += 2 * vel;
  }
  b1.Quantise();
  v.Quantise();
  std::vector<int32_t> decoded;
  SoftDeltaRefs two{.base = b1.q, .base_distance = 1, .base2 = b2.q, .base2_distance = 1,
                    .dt_ms = 20, .base_dt_ms = 20};
  RoundTrip rt = EncodeDecode(v, two, 3, 1100, &decoded);
  ExpectWithinLattice(v, decoded);
  ASSERT_EQ(rt.modes.size(), 1u);
  EXPECT_EQ(rt.modes[0] & 3, kSoftExtrapolate);
  SoftDeltaRefs one{.base = b1.q, .base_distance = 1};
  RoundTrip rt1 = EncodeDecode(v, one, 3, 1100, &decoded);
  EXPECT_LT(rt.bytes * 2, rt1.bytes);
}

std::vector<uint8_t> OneRecordPayload() {
  std::mt19937 rng(1);
  Body b = RandomBody(rng, 50);
  Body base = Move(b, rng, 0.002f);
  std::vector<uint8_t> payload(1100);
  size_t pos = BeginSoftDeltaPayload(500, payload);
  SoftDeltaScratch scratch;
  SoftDeltaRecordInput in{.entity_id = 7, .version = 5, .age_ms = 3, .q = b.q, .first = 0,
                          .max_count = 50, .refs = {.base = base.q, .base_distance = 2}};
  uint32_t count = 0;
  pos += EncodeSoftDeltaRecord(in, std::span<uint8_t>(payload).subspan(pos), &scratch, &count, nullptr);
  payload.resize(pos);
  return payload;
}

TEST(SoftDeltaCodec, MalformedRecordsAreRejected) {
  const std::vector<uint8_t> good = OneRecordPayload();
  SoftDeltaRecord r;
  size_t pos = kSoftDeltaHeaderSize;
  ASSERT_TRUE(ParseSoftDeltaRecord(good, 500, 1 << 16, &pos, &r).ok());
  EXPECT_EQ(r.time_ms, 497u);
  EXPECT_EQ(r.base_version, 3u);
  // Every truncation fails to parse (or, past the header, leaves the coded span short).
  for (size_t cut = kSoftDeltaHeaderSize; cut < good.size(); ++cut) {
    std::vector<uint8_t> t(good.begin(), good.begin() + static_cast<ptrdiff_t>(cut));
    size_t at = kSoftDeltaHeaderSize;
    EXPECT_FALSE(ParseSoftDeltaRecord(t, 500, 1 << 16, &at, &r).ok()) << cut;
  }
  auto with = [&](size_t index, uint8_t value) {
    std::vector<uint8_t> p = good;
    p[index] = value;
    size_t at = kSoftDeltaHeaderSize;
    return ParseSoftDeltaRecord(p, 500, 1 << 16, &at, &r);
  };
  // Layout: id 7, version 5, age 3, total 50, first 0, count 50, mode, distance 2, ...
  const size_t id = 5, version = 6, total = 8, first = 9, count = 10, mode = 11, dist = 12;
  (void)id;
  EXPECT_FALSE(with(version, 0).ok());       // version 0
  EXPECT_FALSE(with(total, 0).ok());         // no particles
  EXPECT_FALSE(with(first, 50).ok());        // first beyond total
  EXPECT_FALSE(with(count, 0).ok());         // empty record
  EXPECT_FALSE(with(count, 51).ok());        // past total
  EXPECT_FALSE(with(mode, 0x13).ok());       // unknown mode bits
  EXPECT_FALSE(with(mode, 0x03).ok());       // unknown predictor
  EXPECT_FALSE(with(dist, 0).ok());          // baseline distance 0
  EXPECT_FALSE(with(dist, 5).ok());          // baseline below version 1
  {
    size_t at = kSoftDeltaHeaderSize;
    EXPECT_FALSE(ParseSoftDeltaRecord(good, 500, 49, &at, &r).ok());  // total over the limit
  }
  // Decoding against a baseline of another size, or without one, is refused.
  pos = kSoftDeltaHeaderSize;
  ASSERT_TRUE(ParseSoftDeltaRecord(good, 500, 1 << 16, &pos, &r).ok());
  std::vector<int32_t> out(150), small(30);
  EXPECT_FALSE(DecodeSoftDeltaResiduals(r, {}, out).ok());
  EXPECT_FALSE(DecodeSoftDeltaResiduals(r, {.base = small, .base_distance = 2}, out).ok());
}

TEST(SoftDeltaCodec, GarbageResidualsNeverLeaveTheLattice) {
  std::mt19937 rng(13);
  std::vector<int32_t> base(300, 1000), base2(300, -1000), out(300);
  for (int trial = 0; trial < 2000; ++trial) {
    std::vector<uint8_t> coded(rng() % 64);
    for (auto& b : coded) b = static_cast<uint8_t>(rng());
    SoftDeltaRecord r;
    r.version = 10;
    r.total = 100;
    r.first = static_cast<uint32_t>(rng() % 100);
    r.count = 1 + static_cast<uint32_t>(rng() % (100 - r.first));
    r.mode = static_cast<uint8_t>(rng() % 3) | static_cast<uint8_t>(rng() % 4) << 2;
    for (int32_t& o : r.offset) o = static_cast<int32_t>(rng() % 2001) - 1000;
    r.coded = coded;
    SoftDeltaRefs refs{.base = base, .base_distance = 1, .base2 = base2, .base2_distance = 1,
                       .dt_ms = 40000, .base_dt_ms = 1};
    if (DecodeSoftDeltaResiduals(r, refs, out).ok()) {
      for (int32_t v : out) {
        ASSERT_GT(int64_t{v}, -kSoftLatticeLimit);
        ASSERT_LT(int64_t{v}, kSoftLatticeLimit);
      }
    }
  }
}

}  // namespace
}  // namespace edgephys
