// Property writes a relay must refuse, through a real relay on a simulated network: another
// player's owner-only properties, writes without the join token's permission, over a room
// budget (count, bytes, value size) or the write rate, unknown entities, and malformed writes
// (unknown type tag or authority, oversized or empty key, NaN or infinite double/vec3/quat, a
// vec3 missing). Each is refused with its reason, counted, and reaches nobody; the other
// players' writes go on.
#include <gtest/gtest.h>

#include <flatbuffers/flatbuffers.h>

#include <cmath>
#include <string>
#include <vector>

#include "client/client_testing.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/property_codec.h"
#include "relay/room_host.h"
#include "tests/integration/property_inbox.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

using schema::RejectReason;

uint64_t BudgetRefusals(RelayCounters& c, BudgetKind kind) {
  return c.budget_refusals[static_cast<size_t>(kind)].load();
}

TEST(PropertiesHostile, OwnerOnlyPropertiesRefuseOthersAnyoneMayWriteTheRest) {
  SimWorld world;
  PropertyInbox ia, ib;
  auto [a, b] = AddJoined(world, "auth", ia, ib);
  Result<uint32_t> box = a.Spawn({});
  ASSERT_TRUE(box.ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*box) != nullptr; }, 5.0));
  ASSERT_TRUE(a.SetProperty(0, "mode", PropertyValue::String("lesson")).ok());  // owner only
  ASSERT_TRUE(a.SetProperty(0, "chat", PropertyValue::Int64(1), PropertyAuthority::kAnyone).ok());
  ASSERT_TRUE(a.SetProperty(*box, "color", PropertyValue::Int64(7)).ok());  // owner only
  ASSERT_TRUE(world.RunUntil([&] { return b.properties().size() == 3; }, 5.0));
  // B may not write A's owner-only room or entity property, nor create an owner-only one on
  // A's entity; it may write the Anyone one and create its own.
  ASSERT_TRUE(b.SetProperty(0, "mode", PropertyValue::String("hacked")).ok());
  ASSERT_TRUE(b.SetProperty(*box, "color", PropertyValue::Int64(0)).ok());
  ASSERT_TRUE(b.SetProperty(*box, "mine", PropertyValue::Int64(0)).ok());
  ASSERT_TRUE(b.CompareAndSetProperty(0, "mode", PropertyValue::String("cas"), 1).ok());
  ASSERT_TRUE(b.SetProperty(0, "chat", PropertyValue::Int64(2)).ok());
  ASSERT_TRUE(b.SetProperty(*box, "label", PropertyValue::String("b's"), PropertyAuthority::kAnyone).ok());
  ASSERT_TRUE(world.RunUntil([&] { return ib.errors.size() >= 4 && a.properties().size() == 4; }, 5.0));
  world.RunFor(0.3);
  EXPECT_EQ(ib.Count(RejectReason::NotOwner), 4u);
  for (const std::string& d : ib.error_details) EXPECT_NE(d.find("property '"), std::string::npos) << d;
  EXPECT_EQ(a.FindProperty(0, "mode")->value, PropertyValue::String("lesson"));
  EXPECT_EQ(b.FindProperty(0, "mode")->version, 1u);
  EXPECT_EQ(a.FindProperty(*box, "color")->value, PropertyValue::Int64(7));
  EXPECT_EQ(a.FindProperty(*box, "mine"), nullptr);
  EXPECT_EQ(a.FindProperty(0, "chat")->value, PropertyValue::Int64(2));
  EXPECT_EQ(a.FindProperty(0, "chat")->writer, 2u);
  EXPECT_EQ(a.FindProperty(*box, "label")->writer, 2u);
  EXPECT_TRUE(ia.errors.empty());
  EXPECT_EQ(RequestsRejected(world.counters(), RejectReason::NotOwner), 4u);
  EXPECT_EQ(world.relay().rooms().at("auth")->property_stats().refused, 4u);
  // The SDK refuses what it can tell is wrong without asking the relay.
  EXPECT_EQ(b.SetProperty(0, "", PropertyValue::Int64(1)).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(b.SetProperty(0, "x", PropertyValue::Double(NAN)).status().code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(b.SetProperty(12345, "x", PropertyValue::Int64(1)).status().code(), StatusCode::kNotFound);
}

TEST(PropertiesHostile, BudgetsPermissionAndRateAreRefusedAndCounted) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.budgets.max_properties = 4;
  config.room_defaults.budgets.max_property_bytes = 200;
  config.room_defaults.budgets.max_property_value_bytes = 100;
  config.room_defaults.budgets.property_writes_per_s_per_player = 20;  // burst 40
  SimWorld world({}, config);
  PropertyInbox ia, ib, ic;
  auto [a, b, c] = AddJoined(world, "budget", ia, ib, Joiner{&ic, kPermissionSpawn | kPermissionMessage});
  ASSERT_TRUE(a.SetProperty(0, "v", PropertyValue::String(std::string(101, 'x'))).ok());  // value
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(a.SetProperty(0, "k" + std::to_string(i), PropertyValue::Int64(i)).ok());
  ASSERT_TRUE(a.SetProperty(0, "k4", PropertyValue::Int64(4)).ok());  // the fifth: count
  ASSERT_TRUE(a.SetProperty(0, "k0", PropertyValue::String(std::string(100, 'y'))).ok());
  ASSERT_TRUE(a.SetProperty(0, "k1", PropertyValue::String(std::string(100, 'z'))).ok());  // bytes
  ASSERT_TRUE(c.SetProperty(0, "c", PropertyValue::Int64(1)).ok());  // no permission
  ASSERT_TRUE(world.RunUntil([&] { return ia.errors.size() >= 3 && ic.errors.size() >= 1; }, 5.0));
  world.RunFor(0.3);
  EXPECT_EQ(ia.Count(RejectReason::OverBudget), 3u);
  EXPECT_EQ(ic.Count(RejectReason::NotPermitted), 1u);
  EXPECT_EQ(BudgetRefusals(world.counters(), BudgetKind::kPropertyValueBytes), 1u);
  EXPECT_EQ(BudgetRefusals(world.counters(), BudgetKind::kRoomProperties), 1u);
  EXPECT_EQ(BudgetRefusals(world.counters(), BudgetKind::kRoomPropertyBytes), 1u);
  EXPECT_NE(ia.error_details[0].find("property_value_bytes"), std::string::npos);
  const RoomHost& room = *world.relay().rooms().at("budget");
  EXPECT_EQ(room.properties().count(), 4u);
  EXPECT_LE(room.properties().bytes(), 200u);
  EXPECT_EQ(b.properties().size(), 4u);
  EXPECT_EQ(b.FindProperty(0, "k0")->value.text, std::string(100, 'y'));
  EXPECT_EQ(b.FindProperty(0, "k1")->value, PropertyValue::Int64(1));
  EXPECT_EQ(b.FindProperty(0, "c"), nullptr);
  // A flood of writes at once: the burst passes, the rest is refused, counted, and not sent.
  const size_t b_changes = ib.changes.size();
  constexpr int kFlood = 200;
  for (int i = 0; i < kFlood; ++i) ASSERT_TRUE(b.SetProperty(0, "k2", PropertyValue::Int64(i)).ok());
  world.RunFor(1.0);
  const size_t limited = ib.Count(RejectReason::RateLimited);
  EXPECT_GT(limited, 100u);
  EXPECT_LT(limited, static_cast<size_t>(kFlood));
  EXPECT_EQ(RequestsRejected(world.counters(), RejectReason::RateLimited), limited);
  // k2 is A's owner-only property: the writes that passed the rate were refused as NotOwner.
  EXPECT_EQ(ib.Count(RejectReason::NotOwner) + limited, static_cast<size_t>(kFlood));
  EXPECT_EQ(ib.changes.size(), b_changes);
  EXPECT_EQ(room.property_stats().refused, 4 + static_cast<uint64_t>(kFlood));
}

// Builds a raw PropertySet the SDK would never send.
std::vector<uint8_t> RawSet(uint32_t entity, const std::string& key, uint8_t type, double real,
                            const schema::Vec3* vec, uint8_t authority = 0) {
  flatbuffers::FlatBufferBuilder fbb(128);
  const auto k = fbb.CreateString(key);
  schema::PropertyValueBuilder vb(fbb);
  vb.add_type(static_cast<schema::PropertyType>(type));
  vb.add_real(real);
  vb.add_number(1);
  if (vec != nullptr) vb.add_vec(vec);
  const auto v = vb.Finish();
  FinishControl(fbb, schema::CreatePropertySet(fbb, entity, k, v, false, 0,
                                               static_cast<schema::PropertyAuthority>(authority), 77));
  return {fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize()};
}

TEST(PropertiesHostile, MalformedWritesAreRefusedCountedAndHarmNoOne) {
  SimWorld world;
  PropertyInbox ia, ib, ic;
  // b writes honestly, c watches
  auto [a, b, c] = AddJoined(world, "bad", ia, ib, ic);
  const schema::Vec3 nan_vec(0, std::nanf(""), 0), good_vec(1, 2, 3);
  const std::vector<std::vector<uint8_t>> bad = {
      RawSet(0, "t", 8, 0, nullptr),                      // unknown type tag
      RawSet(0, "t", 0, 0, nullptr),                      // type None
      RawSet(0, std::string(65, 'k'), 3, 1.0, nullptr),   // key over 64 bytes
      RawSet(0, "", 3, 1.0, nullptr),                     // empty key
      RawSet(0, std::string("a\0b", 3), 3, 1.0, nullptr), // NUL in the key
      RawSet(0, "d", 3, std::nan(""), nullptr),           // NaN double
      RawSet(0, "d", 3, INFINITY, nullptr),               // infinite double
      RawSet(0, "v", 6, 0, &nan_vec),                     // NaN vec3
      RawSet(0, "v", 6, 0, nullptr),                      // vec3 without its value
      RawSet(0, "q", 7, 0, nullptr),                      // quat without its value
      RawSet(0, "a", 6, 0, &good_vec, 5),                 // unknown authority
      RawSet(99, "e", 3, 1.0, nullptr),                   // unknown entity
  };
  for (size_t i = 0; i < bad.size(); ++i) {
    ASSERT_TRUE(ClientTesting::SendReliableUnchecked(a, bad[i]).ok());
    ASSERT_TRUE(b.SetProperty(0, "honest", PropertyValue::Int64(static_cast<int64_t>(i))).ok());
  }
  std::vector<uint8_t> cut = RawSet(0, "d", 3, 1.0, nullptr);
  cut.resize(cut.size() - 8);  // fails verification
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(a, cut).ok());
  ASSERT_TRUE(world.RunUntil([&] { return ia.errors.size() >= bad.size() + 1; }, 5.0));
  world.RunFor(0.5);
  EXPECT_EQ(ia.Count(RejectReason::InvalidMessage), bad.size());  // 11 + the unverifiable one
  EXPECT_EQ(ia.Count(RejectReason::UnknownEntity), 1u);
  EXPECT_EQ(ia.errors.size(), bad.size() + 1);
  // Details name the cause.
  const auto said = [&](const char* what) {
    for (const std::string& d : ia.error_details) {
      if (d.find(what) != std::string::npos) return true;
    }
    return false;
  };
  EXPECT_TRUE(said("unknown property type 8"));
  EXPECT_TRUE(said("longer than 64 bytes"));
  EXPECT_TRUE(said("double value is NaN or infinite"));
  EXPECT_TRUE(said("vec3 value has a NaN"));
  EXPECT_TRUE(said("unknown property authority"));
  // Nothing of A's reached anyone; B's writes all did, in order.
  const RoomHost& room = *world.relay().rooms().at("bad");
  EXPECT_EQ(room.properties().count(), 1u);
  EXPECT_EQ(room.property_stats().refused, bad.size());
  EXPECT_EQ(ic.Versions(0, "honest"), OneTo(static_cast<uint32_t>(bad.size())));
  for (const PropertyRecord& p : ic.changes) EXPECT_EQ(p.writer, 2u);
  EXPECT_TRUE(ib.errors.empty() && ic.errors.empty());
  EXPECT_EQ(RequestsRejected(world.counters(), RejectReason::InvalidMessage), bad.size());
}

}  // namespace
}  // namespace edgephys::testing
