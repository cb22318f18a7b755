// The SDK's decoder table (protocol/state_formats.h): which formats it builds decoders for, and
// that each decodes its own format through the StateDecoder interface and refuses the other's.
#include "protocol/state_formats.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "protocol/delta_codec.h"
#include "protocol/connection.h"
#include "protocol/shared_delta_codec.h"
#include "protocol/testing/shared_delta_harness.h"

namespace edgephys {
namespace {

QuantizationParams DefaultParams() { return *MakeQuantizationParams(QuantizationConfig{}); }

float Distance(const Vec3f& a, const Vec3f& b) {
  return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) +
                   (a.z - b.z) * (a.z - b.z));
}
// The angle between two unit quaternions (degrees).
float AngleDeg(const Quatf& a, const Quatf& b) {
  const double dot = std::fabs(double{a.x} * b.x + double{a.y} * b.y + double{a.z} * b.z +
                               double{a.w} * b.w);
  return static_cast<float>(2.0 * std::acos(std::min(1.0, dot)) * 180.0 / 3.14159265358979);
}

TEST(StateFormats, TheSdkDecodesFormats9And2AndNothingElse) {
  for (int id = 0; id < 256; ++id) {
    const bool decoded = NewStateDecoder(static_cast<uint8_t>(id), DefaultParams()) != nullptr;
    EXPECT_EQ(decoded, id == kSharedDeltaStateFormat || id == kDeltaStateFormat) << id;
  }
}

// Format 2 through the table: 200 random states of 20 entities, every payload acknowledged,
// decode within the lattice (1 mm, 0.1 deg); the format-9 decoder refuses every payload.
TEST(StateFormats, Format2DecodesItsOwnAndTheOtherDecoderRefusesIt) {
  const QuantizationParams params = DefaultParams();
  DeltaEncoder enc(params);
  auto dec = NewStateDecoder(kDeltaStateFormat, params);
  auto other = NewStateDecoder(kSharedDeltaStateFormat, params);
  ASSERT_NE(dec, nullptr);
  ASSERT_NE(other, nullptr);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> pos(-20.f, 20.f), comp(-1.f, 1.f);
  std::vector<uint8_t> buf(kMaxUnreliablePayload);
  StateBatch batch;
  size_t decoded = 0;
  for (int round = 0; round < 10; ++round) {
    std::vector<EntityState> sent;
    enc.Begin(buf, static_cast<uint32_t>(round * 33));
    for (uint32_t id = 1; id <= 20; ++id) {
      EntityState s;
      s.entity_id = id;
      s.position = {pos(rng), pos(rng), pos(rng)};
      Quatf q{comp(rng), comp(rng), comp(rng), comp(rng)};
      const float n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
      s.rotation = {q.x / n, q.y / n, q.z / n, q.w / n};
      ASSERT_TRUE(enc.Add(s));
      sent.push_back(s);
    }
    const size_t size = enc.Finish();
    const std::span<const uint8_t> payload(buf.data(), size);
    enc.OnSent(static_cast<uint16_t>(round + 1), round * 0.033);
    const Status refused = other->Decode(payload, &batch);
    EXPECT_EQ(refused.code(), StatusCode::kMalformed);
    EXPECT_NE(refused.message().find("format-9"), std::string::npos) << refused.message();
    batch.states.clear();
    ASSERT_TRUE(dec->Decode(payload, &batch).ok());
    enc.OnPacketAcked(static_cast<uint16_t>(round + 1));
    ASSERT_EQ(batch.states.size(), sent.size());
    for (size_t i = 0; i < sent.size(); ++i) {
      EXPECT_EQ(batch.states[i].entity_id, sent[i].entity_id);
      EXPECT_LE(Distance(batch.states[i].position, sent[i].position), 0.0009f);
      EXPECT_LE(AngleDeg(batch.states[i].rotation, sent[i].rotation), 0.1f);
      ++decoded;
    }
  }
  EXPECT_EQ(decoded, 200u);
}

// Format 9 through the table, and a forgotten entity: its next delta is skipped and counted as
// a reference to an unknown entity, never decoded into a guess.
TEST(StateFormats, Format9DecodesItsOwnAndForgetDropsTheEntity) {
  testing_util::SharedDeltaHarness h;
  auto dec = NewStateDecoder(kSharedDeltaStateFormat, h.params);
  auto other = NewStateDecoder(kDeltaStateFormat, h.params);
  SharedEntity a;
  EntityState s;
  s.entity_id = 4;
  s.position = {1.25f, 2.5f, -3.0f};
  h.Tick({{&a, s}});
  auto [seq1, p1] = h.Send({{4, &a}});
  StateBatch batch;
  const Status refused = other->Decode(p1, &batch);
  EXPECT_EQ(refused.code(), StatusCode::kMalformed);
  EXPECT_NE(refused.message().find("format-2"), std::string::npos) << refused.message();
  ASSERT_TRUE(dec->Decode(p1, &batch).ok());
  ASSERT_EQ(batch.states.size(), 1u);
  EXPECT_LE(Distance(batch.states[0].position, s.position), 0.0009f);
  h.stream.OnPacketAcked(seq1);

  s.position.x += 0.5f;
  h.Tick({{&a, s}});
  auto [seq2, p2] = h.Send({{4, &a}});
  dec->Forget(4);
  batch.states.clear();
  ASSERT_TRUE(dec->Decode(p2, &batch).ok());
  EXPECT_TRUE(batch.states.empty());
  const auto& stats = static_cast<const SharedDeltaDecoder&>(*dec).stats();
  EXPECT_EQ(stats.unresolved_references, 1u);
  EXPECT_EQ(stats.unknown_entity, 1u);
}

}  // namespace
}  // namespace edgephys
