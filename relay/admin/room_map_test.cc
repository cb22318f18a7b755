// GET /v1/rooms/{id}/map against a real relay on loopback UDP with real SDK clients and the
// relay's embedded PhyS: the HTTP request runs on its own thread while the test thread pumps
// the relay, its admin command queue (RelayAdmin::Tick) and the clients, as relay/main.cc does.
// The positions the map shows are the ones the clients published.
#include <gtest/gtest.h>
#include <httplib.h>

#include <chrono>
#include <cmath>
#include <future>
#include <map>
#include <string>

#include "relay/admin/admin_http.h"
#include "relay/admin/relay_admin.h"
#include "relay/admin/room_map.h"
#include "relay/admin/testing/loopback_admin.h"
#include "tests/integration/harness.h"

namespace edgephys::admin {
namespace {

using nlohmann::json;
using testing::ConnectAndJoinAll;
using testing::LoopbackWorld;
using testing::MintToken;
namespace flags = entity_flags;

class AdminRoomMap : public ::testing::Test {
 protected:
  void SetUp() override {
    AdminHttpOptions options;
    options.key = "map-key";
    server_ = testing::StartLoopbackAdmin(options, &admin_);
    ASSERT_NE(server_, nullptr);
    port_ = testing::AdminPort(*server_);
  }
  void TearDown() override {
    admin_.Close();
    if (server_) server_->Stop();
  }

  void Pump() {
    world_.Step();
    admin_.Tick(world_.Now());
  }

  // GET `path` on an HTTP thread while this thread pumps the relay: {status, JSON body}.
  std::pair<int, json> Get(const std::string& path, const std::string& key = "map-key") {
    auto reply = std::async(std::launch::async, [this, path, key] {
      httplib::Client c("127.0.0.1", port_);
      c.set_connection_timeout(5);
      c.set_read_timeout(5);
      httplib::Headers h;
      if (!key.empty()) h.emplace("Authorization", "Bearer " + key);
      auto r = c.Get(path, h);
      return r ? std::pair<int, std::string>{r->status, r->body}
               : std::pair<int, std::string>{-1, ""};
    });
    for (int i = 0; i < 20000 && reply.wait_for(std::chrono::seconds(0)) != std::future_status::ready;
         ++i) {
      Pump();
    }
    auto [status, body] = reply.get();
    return {status, json::parse(body, nullptr, false)};
  }

  static const json* Find(const json& map, uint32_t id) {
    for (const json& e : map["entities"]) {
      if (e["id"] == id) return &e;
    }
    return nullptr;
  }
  static bool At(const json& e, Vec3f p) {
    // The relay keeps what arrived; an update on the wire is quantised to 1 mm steps.
    return std::fabs(e["x"].get<double>() - p.x) < 1e-3 && std::fabs(e["y"].get<double>() - p.y) < 1e-3 &&
           std::fabs(e["z"].get<double>() - p.z) < 1e-3;
  }

  LoopbackWorld world_;
  RelayAdmin admin_{&world_.relay(), LoopbackWorld::DefaultConfig().room_defaults};
  std::unique_ptr<AdminHttpServer> server_;
  int port_ = 0;
};

TEST_F(AdminRoomMap, ShowsWhatThePlayersPublishedWithKindsOwnersAndPhysics) {
  Client& a = world_.AddClient(MintToken("yard", 11));
  Client& b = world_.AddClient(MintToken("yard", 12));
  ASSERT_TRUE(ConnectAndJoinAll(world_, {&a, &b}, "yard", 5.0));

  auto head = a.Spawn({.position = {1, 1.7f, 2}, .flags = flags::kAvatar, .name = "head"});
  auto hand = a.Spawn({.position = {1.3f, 1.2f, 2.4f}, .flags = flags::kHand});
  SpawnDesc box{.position = {0, 3, 0}, .flags = flags::kOffloaded};
  box.rigid_body = RigidBodySpec{};
  box.colliders.push_back(BoxCollider({0.1f, 0.1f, 0.1f}));
  auto body = a.Spawn(box);
  auto chair = b.Spawn({.position = {-2, 0.5f, 5}});
  SpawnDesc jelly{.position = {0.5f, 1, 0.5f}, .flags = flags::kOffloaded};
  jelly.soft_body = SoftBodySpec{.particles = {0.5f, 1, 0.5f, 0.7f, 1, 0.5f, 0.5f, 1.2f, 0.5f, 0.5f, 1, 0.7f},
                                 .masses = {0.1f, 0.1f, 0.1f, 0.1f},
                                 .springs = {0, 1, 0, 2, 0, 3, 1, 2, 1, 3, 2, 3},
                                 .stiffness = 200,
                                 .damping = 0.1f};
  auto soft = b.Spawn(jelly);
  ASSERT_TRUE(head.ok() && hand.ok() && body.ok() && chair.ok() && soft.ok());

  // Moves published after the spawns: the map must show them, not the spawn positions.
  const Vec3f head_at{3.25f, 1.625f, -4.5f}, chair_at{-2.5f, 0.75f, 6.125f};
  json map;
  bool seen = false;
  for (int i = 0; i < 100 && !seen; ++i) {
    (void)a.PublishTransform(*head, head_at, {0, 0, 0, 1});
    (void)b.PublishTransform(*chair, chair_at, {0, 0, 0, 1});
    world_.RunFor(0.05);
    auto [status, got] = Get("/v1/rooms/yard/map");
    ASSERT_EQ(status, 200) << got.dump();
    map = got;
    const json* h = Find(map, *head);
    const json* c = Find(map, *chair);
    seen = map["entities"].size() == 5 && h != nullptr && c != nullptr && At(*h, head_at) &&
           At(*c, chair_at);
  }
  ASSERT_TRUE(seen) << map.dump();
  EXPECT_EQ(map["room"], "yard");
  EXPECT_EQ(map["total"], 5);
  EXPECT_EQ(map["listed"], 5);
  EXPECT_EQ(map["truncated"], false);
  EXPECT_EQ(map["limit"], kMaxMapEntities);
  EXPECT_EQ(map["players"], json::array({11, 12}));

  const json& h = *Find(map, *head);
  EXPECT_EQ(h["kind"], "avatar");
  EXPECT_EQ(h["owner"], 11);
  EXPECT_EQ(h["simulated"], false);
  const json& hd = *Find(map, *hand);
  EXPECT_EQ(hd["kind"], "hand");
  EXPECT_EQ(hd["owner"], 11);
  EXPECT_TRUE(At(hd, {1.3f, 1.2f, 2.4f})) << hd.dump();  // never moved: its spawn transform
  const json& c = *Find(map, *chair);
  EXPECT_EQ(c["kind"], "object");
  EXPECT_EQ(c["owner"], 12);
  EXPECT_EQ(c["creator"], 12);
  const json& p = *Find(map, *body);
  EXPECT_EQ(p["kind"], "physics_body");
  EXPECT_EQ(p["owner"], 0);  // PhyS owns what it simulates
  EXPECT_EQ(p["creator"], 11);
  EXPECT_EQ(p["simulated"], true);
  const json& sb = *Find(map, *soft);
  EXPECT_EQ(sb["kind"], "soft_body");
  EXPECT_EQ(sb["owner"], 0);
  EXPECT_EQ(sb["creator"], 12);
  EXPECT_EQ(sb["simulated"], true);

  // PhyS moves its body (it falls under gravity, nothing below it).
  bool fell = false;
  for (int i = 0; i < 40 && !fell; ++i) {
    world_.RunFor(0.05);
    auto [status, got] = Get("/v1/rooms/yard/map");
    ASSERT_EQ(status, 200);
    const json* e = Find(got, *body);
    fell = e != nullptr && (*e)["y"].get<double>() < 2.9;
  }
  EXPECT_TRUE(fell) << "the PhyS body never moved on the map";

  // Bounds cover every entity.
  auto [status, now] = Get("/v1/rooms/yard/map");
  ASSERT_EQ(status, 200);
  for (const json& e : now["entities"]) {
    for (int axis = 0; axis < 3; ++axis) {
      const double v = e[std::string(1, "xyz"[axis])].get<double>();
      EXPECT_LE(now["bounds"]["min"][axis].get<double>(), v);
      EXPECT_GE(now["bounds"]["max"][axis].get<double>(), v);
    }
  }
  EXPECT_DOUBLE_EQ(now["bounds"]["min"][0].get<double>(), -2.5);
  EXPECT_DOUBLE_EQ(now["bounds"]["max"][0].get<double>(), 3.25);

  // Capped: the players' avatar and hand first, and the response says what was left out.
  auto [capped_status, capped] = Get("/v1/rooms/yard/map?limit=2");
  ASSERT_EQ(capped_status, 200);
  EXPECT_EQ(capped["listed"], 2);
  EXPECT_EQ(capped["total"], 5);
  EXPECT_EQ(capped["truncated"], true);
  EXPECT_EQ(capped["limit"], 2);
  ASSERT_EQ(capped["entities"].size(), 2u);
  EXPECT_EQ(capped["entities"][0]["id"], *head);
  EXPECT_EQ(capped["entities"][1]["id"], *hand);
}

TEST_F(AdminRoomMap, UnknownRoomMissingKeyAndEmptyRoom) {
  auto [status, body] = Get("/v1/rooms/nowhere/map");
  EXPECT_EQ(status, 404);
  EXPECT_EQ(body["error"]["code"], "room_not_found");
  EXPECT_EQ(body["error"]["message"], "no room 'nowhere' on this relay");
  auto [no_key, refused] = Get("/v1/rooms/nowhere/map", "");
  EXPECT_EQ(no_key, 401);
  EXPECT_EQ(refused["error"]["code"], "unauthorized");

  ASSERT_TRUE(world_.relay().CreateRoom("empty", LoopbackWorld::DefaultConfig().room_defaults,
                                        world_.Now()).ok());
  auto [ok, empty] = Get("/v1/rooms/empty/map");
  EXPECT_EQ(ok, 200);
  EXPECT_EQ(empty["entities"], json::array());
  EXPECT_EQ(empty["total"], 0);
  EXPECT_EQ(empty["truncated"], false);
  EXPECT_TRUE(empty["bounds"].is_null());
}

}  // namespace
}  // namespace edgephys::admin
