// Room lifecycle and authority rules, on a perfect simulated network with a fake clock.
#include <gtest/gtest.h>

#include "tests/integration/sim_world.h"
#include "client/client_testing.h"

namespace edgephys::testing {
namespace {

using schema::RejectReason;

struct Errors : ClientListener {
  std::vector<uint16_t> reasons;
  void OnError(uint16_t reason, uint32_t, std::string_view) override { reasons.push_back(reason); }
};

void Join(SimWorld& world, Client& c, const std::string& room) {
  ASSERT_TRUE(world.RunUntil([&] { return c.state() == ClientState::kConnected; }, 5.0));
  ASSERT_TRUE(c.JoinRoom(room).ok());
  ASSERT_TRUE(world.RunUntil([&] { return c.joined(); }, 5.0));
}

flatbuffers::FlatBufferBuilder DespawnMessage(uint32_t id) {
  flatbuffers::FlatBufferBuilder fbb;
  FinishControl(fbb, schema::CreateDespawn(fbb, id));
  return fbb;
}

TEST(RelayRooms, EmptyRoomClosesAfterItsTtlAndOperatorRoomsKeepTheirSettings) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.idle_ttl_s = 2.0;
  SimWorld world({}, config);
  RoomConfig custom;
  custom.capacity = 3;
  custom.tick_rate_hz = 10;
  custom.idle_ttl_s = 1.0;
  ASSERT_TRUE(world.relay().CreateRoom("stage", custom, world.Now()).ok());
  EXPECT_FALSE(world.relay().CreateRoom("", custom, world.Now()).ok());
  RoomConfig bad = custom;
  bad.tick_rate_hz = 0;
  EXPECT_FALSE(world.relay().CreateRoom("x", bad, world.Now()).ok());

  Client& a = world.AddClient(MintToken("stage", 1));
  Join(world, a, "stage");
  EXPECT_EQ(world.relay().FindRoom("stage")->config().capacity, 3u);
  EXPECT_EQ(world.relay().CreateRoom("stage", custom, world.Now()).code(), StatusCode::kAlreadyExists);
  ASSERT_TRUE(a.Spawn({.flags = 1 /* Persistent */}).ok());
  world.RunFor(0.2);
  ASSERT_TRUE(a.LeaveRoom().ok());
  world.RunFor(0.5);
  ASSERT_NE(world.relay().FindRoom("stage"), nullptr);  // within its TTL, entity persists
  EXPECT_EQ(world.relay().FindRoom("stage")->entities().size(), 1u);
  world.RunFor(0.7);
  EXPECT_EQ(world.relay().FindRoom("stage"), nullptr);
  EXPECT_EQ(world.counters().rooms.load(), 0);
  EXPECT_EQ(world.counters().entities.load(), 0);
}

TEST(RelayRooms, NobodyDespawnsOrSpawnsInAnotherPlayersName) {
  SimWorld world;
  Errors errors;
  Client& a = world.AddClient(MintToken("r", 1));
  Client& b = world.AddClient(MintToken("r", 2), &errors);
  Join(world, a, "r");
  Join(world, b, "r");
  auto id = a.Spawn({});
  ASSERT_TRUE(world.RunUntil([&] { return b.FindEntity(*id) != nullptr; }, 2.0));

  auto msg = DespawnMessage(*id);
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(b, {msg.GetBufferPointer(), msg.GetSize()}).ok());
  auto unknown = DespawnMessage(424242);
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(b, {unknown.GetBufferPointer(), unknown.GetSize()}).ok());
  // A spawn in A's id block, claiming to be A's.
  flatbuffers::FlatBufferBuilder fbb;
  schema::Transform t(schema::Vec3(0, 0, 0), schema::Quat(0, 0, 0, 1), schema::Vec3(1, 1, 1));
  schema::ContainerBuilder cb(fbb);
  cb.add_entity_id(a.entity_id_base() + 500);
  cb.add_owner(a.player_id());
  cb.add_transform(&t);
  auto c = cb.Finish();
  FinishControl(fbb, schema::CreateSpawn(fbb, c));
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(b, {fbb.GetBufferPointer(), fbb.GetSize()}).ok());
  std::vector<uint8_t> garbage(50, 0x33);
  ASSERT_TRUE(ClientTesting::SendReliableUnchecked(b, garbage).ok());

  ASSERT_TRUE(world.RunUntil([&] { return errors.reasons.size() >= 4; }, 2.0));
  EXPECT_EQ(errors.reasons[0], static_cast<uint16_t>(RejectReason::NotOwner));
  EXPECT_EQ(errors.reasons[1], static_cast<uint16_t>(RejectReason::UnknownEntity));
  EXPECT_EQ(errors.reasons[2], static_cast<uint16_t>(RejectReason::NotOwner));
  EXPECT_EQ(errors.reasons[3], static_cast<uint16_t>(RejectReason::InvalidMessage));
  EXPECT_EQ(world.relay().FindRoom("r")->entities().count(*id), 1u);
  EXPECT_EQ(world.relay().FindRoom("r")->entities().size(), 1u);
  EXPECT_EQ(world.counters().requests_rejected[static_cast<size_t>(RejectReason::NotOwner)].load(), 2u);
  EXPECT_NE(a.stats(), nullptr);
  EXPECT_EQ(a.state(), ClientState::kConnected);
}

TEST(RelayRooms, SpectatorTokensCannotSpawnAndEntityLimitHolds) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.max_entities_per_player = 3;
  SimWorld world({}, config);
  Errors spectator_errors, player_errors;
  Client& spectator = world.AddClient(MintToken("s", 1, 3600, /*permissions=*/0), &spectator_errors);
  Client& player = world.AddClient(MintToken("s", 2), &player_errors);
  Join(world, spectator, "s");
  Join(world, player, "s");
  ASSERT_TRUE(spectator.Spawn({}).ok());  // the SDK sends; the relay refuses
  for (int i = 0; i < 4; ++i) ASSERT_TRUE(player.Spawn({}).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return !spectator_errors.reasons.empty() && !player_errors.reasons.empty();
  }, 2.0));
  EXPECT_EQ(spectator_errors.reasons[0], static_cast<uint16_t>(RejectReason::NotOwner));
  EXPECT_EQ(player_errors.reasons[0], static_cast<uint16_t>(RejectReason::EntityLimit));
  EXPECT_EQ(world.relay().FindRoom("s")->entities().size(), 3u);
}

TEST(RelayRooms, ANewPlayerNeverGetsTheIdBlockOfPersistentEntities) {
  SimWorld world;
  Errors errors;
  Client& a = world.AddClient(MintToken("keep", 1));
  Join(world, a, "keep");
  auto kept = a.Spawn({.flags = 1 /* Persistent */});
  ASSERT_TRUE(kept.ok());
  world.RunFor(0.2);
  ASSERT_TRUE(a.LeaveRoom().ok());
  world.RunFor(0.2);
  Client& b = world.AddClient(MintToken("keep", 2), &errors);
  Join(world, b, "keep");
  EXPECT_NE(b.entity_id_base(), *kept / kEntityIdBlock * kEntityIdBlock);
  auto fresh = b.Spawn({});
  ASSERT_TRUE(fresh.ok());
  world.RunFor(0.3);
  EXPECT_TRUE(errors.reasons.empty()) << "reason " << errors.reasons.front();
  EXPECT_EQ(world.relay().FindRoom("keep")->entities().size(), 2u);
}

TEST(RelayRooms, SamePlayerReconnectingReplacesItsOldSession) {
  SimWorld world;
  Client& first = world.AddClient(MintToken("p", 9));
  Join(world, first, "p");
  Client& second = world.AddClient(MintToken("p", 9));
  Join(world, second, "p");
  ASSERT_TRUE(world.RunUntil([&] { return first.state() == ClientState::kDisconnected; }, 2.0));
  EXPECT_EQ(first.disconnect_reason(), DisconnectReason::kKicked);
  EXPECT_EQ(world.relay().session_count(), 1u);
  EXPECT_EQ(world.relay().FindRoom("p")->size(), 1u);
}

}  // namespace
}  // namespace edgephys::testing
