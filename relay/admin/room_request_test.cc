#include "relay/admin/room_request.h"

#include <gtest/gtest.h>

namespace edgephys::admin {
namespace {

using nlohmann::json;

Result<RoomRequest> Parse(const std::string& text) {
  return ParseRoomRequest(json::parse(text), RoomConfig{});
}

TEST(RoomRequestTest, OnlyIdTakesTheDefaults) {
  auto r = Parse(R"({"id": "lobby"})");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  EXPECT_EQ(r->id, "lobby");
  EXPECT_EQ(r->config.capacity, RoomConfig{}.capacity);
  EXPECT_TRUE(r->config.physics);
}

TEST(RoomRequestTest, EveryFieldMapsOntoTheRoomConfig) {
  auto r = Parse(R"({"id": "arena", "capacity": 16, "ttl_s": 600, "tick_rate_hz": 30,
                     "send_rates_hz": {"critical": 40, "normal": 10, "ambient": 5,
                                       "soft_touched": 30},
                     "physics": false, "bounds": {"half_extent_m": 100},
                     "max_entities_per_player": 50})");
  ASSERT_TRUE(r.ok()) << r.status().ToString();
  const RoomConfig& c = r->config;
  EXPECT_EQ(c.capacity, 16u);
  EXPECT_EQ(c.idle_ttl_s, 600);
  EXPECT_EQ(c.tick_rate_hz, 30);
  EXPECT_EQ(c.replication.critical_hz, 40);
  EXPECT_EQ(c.replication.normal_hz, 10);
  EXPECT_EQ(c.replication.ambient_hz, 5);
  EXPECT_EQ(c.replication.soft_touched_hz, 30);
  EXPECT_FALSE(c.physics);
  EXPECT_EQ(c.replication.bounds_half_extent_m, 100.0f);
  EXPECT_EQ(c.max_entities_per_player, 50u);
  // And back: the view shows what was asked.
  json view = RoomConfigJson(c);
  EXPECT_EQ(view["capacity"], 16);
  EXPECT_EQ(view["bounds"]["half_extent_m"], 100.0);
  EXPECT_EQ(view["physics"], false);
  EXPECT_EQ(view["send_rates_hz"]["soft_touched"], 30.0);
}

TEST(RoomRequestTest, RefusesBadInputNamingTheField) {
  struct Case {
    const char* body;
    const char* mentions;
  };
  for (const Case& c : std::initializer_list<Case>{
           {R"({})", "'id'"},
           {R"({"id": 7})", "'id'"},
           {R"({"id": ""})", "'id'"},
           {R"({"id": "a/b"})", "'id'"},
           {R"({"id": "x", "colour": "red"})", "unknown field 'colour'"},
           {R"({"id": "x", "capacity": 0})", "'capacity'"},
           {R"({"id": "x", "capacity": 2.5})", "'capacity'"},
           {R"({"id": "x", "capacity": 70000})", "'capacity'"},
           {R"({"id": "x", "capacity": "16"})", "'capacity'"},
           {R"({"id": "x", "tick_rate_hz": 0})", "'tick_rate_hz'"},
           {R"({"id": "x", "ttl_s": -1})", "'ttl_s'"},
           {R"({"id": "x", "physics": "yes"})", "'physics'"},
           {R"({"id": "x", "send_rates_hz": {"fast": 5}})", "send_rates_hz.fast"},
           {R"({"id": "x", "send_rates_hz": {"critical": 500}})", "send_rates_hz.critical"},
           {R"({"id": "x", "send_rates_hz": 5})", "send_rates_hz"},
           {R"({"id": "x", "send_rates_hz": {"soft_touched": 0}})", "send_rates_hz.soft_touched"},
           {R"({"id": "x", "send_rates_hz": {"soft_touched": "24"}})",
            "send_rates_hz.soft_touched"},
           {R"({"id": "x", "bounds": {"min": [0, 0, 0]}})", "bounds.min"},
           {R"({"id": "x", "bounds": {"half_extent_m": 0}})", "bounds.half_extent_m"},
           {R"({"id": "x", "max_entities_per_player": 0})", "max_entities_per_player"},
       }) {
    auto r = Parse(c.body);
    ASSERT_FALSE(r.ok()) << c.body;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidArgument) << c.body;
    EXPECT_NE(std::string(r.status().reason()).find(c.mentions), std::string::npos)
        << c.body << " -> " << r.status().reason();
  }
}

TEST(RoomRequestTest, RoomIds) {
  EXPECT_TRUE(IsValidRoomId("lobby-1.eu west"));
  EXPECT_FALSE(IsValidRoomId(""));
  EXPECT_FALSE(IsValidRoomId(std::string(65, 'a')));
  EXPECT_FALSE(IsValidRoomId("a\nb"));
  EXPECT_FALSE(IsValidRoomId("a/b"));
}

}  // namespace
}  // namespace edgephys::admin
