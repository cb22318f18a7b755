// Hostile clients against a live relay on loopback (issue 14): what one player with a valid
// join token can do to a room must not make the room unjoinable.
#include <gtest/gtest.h>

#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

constexpr uint32_t kPersistent = static_cast<uint32_t>(schema::EntityFlags::Persistent);

// Finding 2: persistent entities with huge names (each under --max-spawn-bytes) summed past a
// joiner's reliable queue, and every late joiner was disconnected with ReliableOverflow. The
// join now streams paced within the joiner's reliable budget.
TEST(Hostile, HugeRoomStateStreamsToALateJoinerInsteadOfOverflowingIt) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.connection.max_pending_reliable_bytes = 4u << 20;  // the relay's queue per client
  config.limits.bytes_per_s = 0;
  config.limits.packets_per_s = 0;
  config.room_defaults.budgets.max_name_bytes = 300000;  // the attack's names, allowed here
  LoopbackWorld world(config);
  Client& attacker = world.AddClient(MintToken("r", 1));
  ASSERT_TRUE(world.RunUntil([&] { return attacker.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(attacker.JoinRoom("r").ok());
  ASSERT_TRUE(world.RunUntil([&] { return attacker.joined(); }, 3.0));
  constexpr int kEntities = 18;  // 18 x 250 KB = 4.5 MB > the joiner's 4 MB queue
  for (int i = 0; i < kEntities; ++i) {
    auto id = attacker.Spawn({.position = {float(i), 0, 0}, .flags = kPersistent,
                              .name = std::string(250000, char('a' + i))});
    ASSERT_TRUE(id.ok()) << id.status().ToString();
    ASSERT_TRUE(world.RunUntil([&] { return world.relay().FindRoom("r")->entities().size() ==
                                            size_t(i + 1); }, 5.0)) << i;
  }
  Client& joiner = world.AddClient(MintToken("r", 2));
  ASSERT_TRUE(world.RunUntil([&] { return joiner.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(joiner.JoinRoom("r").ok());
  ASSERT_TRUE(world.RunUntil([&] {
    return joiner.entities().size() == kEntities || joiner.state() != ClientState::kConnected;
  }, 20.0));
  EXPECT_EQ(joiner.state(), ClientState::kConnected)
      << "disconnected: " << static_cast<int>(joiner.disconnect_reason());
  EXPECT_EQ(joiner.entities().size(), size_t(kEntities));
  EXPECT_EQ(world.counters().disconnects[size_t(DisconnectReason::kReliableOverflow)].load(), 0u);
}

}  // namespace
}  // namespace edgephys::testing
