// The relay ticks rooms of more than Relay::kBulkRoomEntities entities after the others, whose
// datagrams are sent first (Relay::TickDueRooms): a bulk room (a PhyS scene of thousands of
// bodies) never delays a light room's hand poses within one update, whatever the rooms' names
// (rooms_ is ordered by name, and "a-bulk" sorts first). Serial (one thread) and fork-join.
#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <vector>

#include "protocol/testing/in_memory_network.h"
#include "protocol/testing/tap_socket.h"
#include "tests/integration/bulk_rooms.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

class TickOrderTest : public ::testing::TestWithParam<size_t> {
 protected:
  void Run() {
    const RelayConfig config = BulkRoomsConfig(GetParam());
    const Endpoint relay_at(asio::ip::make_address("10.0.0.1"), 7777);
    auto relay_raw = network_.CreateSocket(relay_at);
    TapSocket socket(relay_raw.get());
    std::vector<Endpoint> sent_to;  // where this update's datagrams went, in order
    socket.on_send = [&](const Endpoint& to, std::span<const uint8_t>) { sent_to.push_back(to); };
    RelayCounters counters;
    Relay relay(config, &socket, &counters);
    std::vector<BulkRoomsMember> members;
    ConnectBulkRoomsMembers(network_, relay_at, config, now_, &members);
    ASSERT_FALSE(HasFatalFailure());
    auto step = [&](double dt) {
      now_ += dt;
      relay.Update(now_, UnixNow());
      for (BulkRoomsMember& m : members) m.Update(now_);
    };
    for (int i = 0; i < 400 && !(members[0].client->joined() && members[3].client->joined()); ++i) step(0.005);
    for (BulkRoomsMember& m : members) ASSERT_TRUE(m.client->joined());
    std::vector<uint32_t> bulk, light;
    SpawnBulkAndLight(members, step, &bulk, &light);
    ASSERT_FALSE(HasFatalFailure());
    // Everything moves; steps of a whole tick interval, so both rooms tick in every update.
    const Endpoint bulk_receiver = members[1].socket->LocalEndpoint();
    const Endpoint light_receiver = members[3].socket->LocalEndpoint();
    int both = 0;
    for (int t = 1; t <= 30; ++t) {
      for (size_t i = 0; i < bulk.size(); ++i) {
        (void)members[0].client->PublishTransform(bulk[i], {0.01f * i, 0.001f * t, 0}, {});
      }
      (void)members[2].client->PublishTransform(light[0], {0.01f * t, 1, 0}, {});
      sent_to.clear();
      step(1.0 / 30);
      // In this update: the first datagram to the light room's receiver must come before the
      // first to the bulk room's receiver.
      int first_bulk = -1, first_light = -1;
      for (size_t i = 0; i < sent_to.size(); ++i) {
        if (sent_to[i] == bulk_receiver && first_bulk < 0) first_bulk = static_cast<int>(i);
        if (sent_to[i] == light_receiver && first_light < 0) first_light = static_cast<int>(i);
      }
      if (first_bulk < 0 || first_light < 0) continue;
      ++both;
      EXPECT_LT(first_light, first_bulk) << "update " << t;
    }
    EXPECT_GE(both, 10);  // both rooms sent in the same update often enough to tell
  }

  InMemoryNetwork network_;
  double now_ = 0;
};

TEST_P(TickOrderTest, ALightRoomIsSentBeforeABulkRoomInTheSameUpdate) { Run(); }

INSTANTIATE_TEST_SUITE_P(Threads, TickOrderTest, ::testing::Values(size_t{1}, size_t{2}));

}  // namespace
}  // namespace edgephys::testing
