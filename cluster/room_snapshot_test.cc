#include "cluster/room_snapshot.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

namespace edgephys::cluster {
namespace {

RoomSnapshot Sample() {
  RoomSnapshot s;
  s.room = "arena";
  s.written_unix_ms = 1234567;
  s.slots = {{7, 1}, {9, 2}};
  EntitySnapshot a;
  a.id = kEntityIdBlock + 1;
  a.owner = 7;
  a.creator = 7;
  a.flags = 1;
  a.physics_role = 2;
  a.spawn_seq = 3;
  a.state = {a.id, {1, 2, 3}, {0, 0, 0, 1}};
  a.linear_velocity = {0.5f, 0, 0};
  a.angular_velocity = {0, 1, 0};
  a.nodes = {{1, 1, 1}, {2, 2, 2}};
  a.spawn = {1, 2, 3, 4, 5};
  a.authority_seq = 4;
  a.former_owner = 9;
  a.takeover_allowed = true;
  a.on_owner_leave = 2;
  s.entities.push_back(a);
  EntitySnapshot b;
  b.id = 2 * kEntityIdBlock + 5;
  b.owner = 0;
  b.creator = 9;
  b.state = {b.id, {-1, 0, 0}, {0, 0, 0, 1}};
  s.entities.push_back(b);
  const auto prop = [](uint32_t entity, const char* key, PropertyValue v, uint32_t version) {
    PropertySnapshot p;
    p.entity_id = entity;
    p.key = key;
    p.value = std::move(v);
    p.version = version;
    p.writer = 9;
    p.owner = entity == 0 ? 7 : 0;
    p.authority = entity == 0 ? PropertyAuthority::kAnyone : PropertyAuthority::kOwner;
    p.request_id = version + 100;
    return p;
  };
  s.properties = {prop(0, "step", PropertyValue::Int64(-5), 3),
                  prop(0, "lit", PropertyValue::Bool(true), 1),
                  prop(0, "gain", PropertyValue::Double(0.25), 2),
                  prop(0, "title", PropertyValue::String("caf\xc3\xa9"), 4),
                  prop(0, "blob", PropertyValue::Bytes(std::string("\0\1\2", 3)), 1),
                  prop(a.id, "tip", PropertyValue::Vec3({1, -2, 3}), 7),
                  prop(a.id, "aim", PropertyValue::Quat({0, 0, 1, 0}), 2)};
  return s;
}

TEST(RoomSnapshot, RoundTrips) {
  RoomSnapshot s = Sample();
  auto bytes = EncodeRoomSnapshot(s);
  auto back = DecodeRoomSnapshot(bytes);
  ASSERT_TRUE(back.ok()) << back.status().ToString();
  EXPECT_EQ(back->room, "arena");
  EXPECT_EQ(back->written_unix_ms, 1234567u);
  ASSERT_EQ(back->slots.size(), 2u);
  EXPECT_EQ(back->slots[1].player_id, 9u);
  EXPECT_EQ(back->slots[1].slot, 2u);
  ASSERT_EQ(back->entities.size(), 2u);
  const EntitySnapshot& a = back->entities[0];
  EXPECT_EQ(a.id, s.entities[0].id);
  EXPECT_EQ(a.owner, 7u);
  EXPECT_EQ(a.physics_role, 2);
  EXPECT_EQ(a.state.entity_id, a.id);
  EXPECT_FLOAT_EQ(a.state.position.z, 3);
  EXPECT_FLOAT_EQ(a.linear_velocity.x, 0.5f);
  ASSERT_EQ(a.nodes.size(), 2u);
  EXPECT_FLOAT_EQ(a.nodes[1].y, 2);
  EXPECT_EQ(a.spawn, s.entities[0].spawn);
  EXPECT_EQ(back->entities[1].creator, 9u);
  ASSERT_EQ(back->properties.size(), s.properties.size());
  for (size_t i = 0; i < s.properties.size(); ++i) {
    const PropertySnapshot& want = s.properties[i];
    const PropertySnapshot& got = back->properties[i];
    EXPECT_EQ(got.entity_id, want.entity_id) << want.key;
    EXPECT_EQ(got.key, want.key);
    EXPECT_EQ(got.value, want.value) << want.key;
    EXPECT_EQ(got.version, want.version);
    EXPECT_EQ(got.writer, want.writer);
    EXPECT_EQ(got.owner, want.owner);
    EXPECT_EQ(got.authority, want.authority);
    EXPECT_EQ(got.request_id, want.request_id);
  }
}

TEST(RoomSnapshot, BadPropertiesAreRefused) {
  const auto refused = [](auto change) {
    RoomSnapshot s = Sample();
    change(s.properties[5]);
    return !DecodeRoomSnapshot(EncodeRoomSnapshot(s)).ok();
  };
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.value.vec.y = std::nanf(""); }));
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.value = PropertyValue::Double(INFINITY); }));
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.key.clear(); }));
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.key.assign(65, 'k'); }));
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.version = 0; }));
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.authority = static_cast<PropertyAuthority>(2); }));
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.value.type = static_cast<PropertyType>(8); }));
  EXPECT_TRUE(refused([](PropertySnapshot& p) { p.value = PropertyValue::Bool(true), p.value.number = 2; }));
  EXPECT_FALSE(refused([](PropertySnapshot&) {}));
}

// Each entity's ownership record: u32 id, u32 authority_seq, u32 former owner, u8, u8.
constexpr size_t kOwnershipRecord = 14;

TEST(RoomSnapshot, OwnershipRoundTripsAndBadValuesAreRefused) {
  auto back = DecodeRoomSnapshot(EncodeRoomSnapshot(Sample()));
  ASSERT_TRUE(back.ok());
  const EntitySnapshot& a = back->entities[0];
  EXPECT_EQ(a.authority_seq, 4u);
  EXPECT_EQ(a.former_owner, 9u);
  EXPECT_TRUE(a.takeover_allowed);
  EXPECT_EQ(a.on_owner_leave, 2);
  const EntitySnapshot& b = back->entities[1];
  EXPECT_EQ(b.authority_seq, 0u);
  EXPECT_FALSE(b.takeover_allowed);
  EXPECT_EQ(b.on_owner_leave, 0);
  RoomSnapshot s = Sample();
  s.entities[1].on_owner_leave = kMaxOwnerLeave + 1;  // an unknown choice
  EXPECT_FALSE(DecodeRoomSnapshot(EncodeRoomSnapshot(s)).ok());
  std::vector<uint8_t> bytes = EncodeRoomSnapshot(Sample());
  bytes[bytes.size() - 2] = 2;  // the last entity's takeover byte: neither 0 nor 1
  EXPECT_FALSE(DecodeRoomSnapshot(bytes).ok());
  bytes = EncodeRoomSnapshot(Sample());
  bytes[bytes.size() - kOwnershipRecord] ^= 1;  // the record names another entity
  EXPECT_FALSE(DecodeRoomSnapshot(bytes).ok());
}

TEST(RoomSnapshot, VersionTwoWithoutOwnershipIsStillRead) {
  std::vector<uint8_t> bytes = EncodeRoomSnapshot(Sample());
  bytes[4] = 2;
  bytes.resize(bytes.size() - 4 - 2 * kOwnershipRecord);
  auto back = DecodeRoomSnapshot(bytes);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->properties.size(), Sample().properties.size());
  EXPECT_EQ(back->entities[0].authority_seq, 0u);
  EXPECT_EQ(back->entities[0].on_owner_leave, 0);
}

TEST(RoomSnapshot, VersionOneWithoutPropertiesIsStillRead) {
  RoomSnapshot s = Sample();
  s.properties.clear();
  std::vector<uint8_t> bytes = EncodeRoomSnapshot(s);
  bytes[4] = 1;                           // version
  bytes.resize(bytes.size() - 4 - 4 - 2 * kOwnershipRecord);  // no property count, no ownership
  auto back = DecodeRoomSnapshot(bytes);
  ASSERT_TRUE(back.ok());
  EXPECT_EQ(back->entities.size(), 2u);
  EXPECT_TRUE(back->properties.empty());
}

TEST(RoomSnapshot, EveryTruncationIsRefused) {
  auto bytes = EncodeRoomSnapshot(Sample());
  for (size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_FALSE(DecodeRoomSnapshot(std::span<const uint8_t>(bytes.data(), n)).ok()) << n;
  }
  bytes.push_back(0);  // trailing garbage
  EXPECT_FALSE(DecodeRoomSnapshot(bytes).ok());
}

TEST(RoomSnapshot, NonFiniteAndOutOfRangeValuesAreRefused) {
  RoomSnapshot s = Sample();
  s.entities[0].state.position.x = std::nanf("");
  EXPECT_FALSE(DecodeRoomSnapshot(EncodeRoomSnapshot(s)).ok());
  s = Sample();
  s.entities[1].physics_role = 9;
  EXPECT_FALSE(DecodeRoomSnapshot(EncodeRoomSnapshot(s)).ok());
  s = Sample();
  s.slots[0].slot = kEntityIdBlock;
  EXPECT_FALSE(DecodeRoomSnapshot(EncodeRoomSnapshot(s)).ok());
}

TEST(RoomSnapshot, RandomGarbageNeverCrashes) {
  std::mt19937 rng(12);
  auto good = EncodeRoomSnapshot(Sample());
  for (int i = 0; i < 5000; ++i) {
    std::vector<uint8_t> bytes = good;
    int flips = 1 + static_cast<int>(rng() % 4);
    for (int f = 0; f < flips; ++f) bytes[rng() % bytes.size()] = static_cast<uint8_t>(rng());
    (void)DecodeRoomSnapshot(bytes);  // any result; must not crash or over-read (ASan)
    std::vector<uint8_t> noise(rng() % 256);
    for (auto& b : noise) b = static_cast<uint8_t>(rng());
    EXPECT_FALSE(DecodeRoomSnapshot(noise).ok());
  }
}

}  // namespace
}  // namespace edgephys::cluster
