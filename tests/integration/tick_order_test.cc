// The relay ticks rooms of more than Relay::kBulkRoomEntities entities after the others, whose
// datagrams are sent first (Relay::TickDueRooms): a bulk room (a PhyS scene of thousands of
// bodies) never delays a light room's hand poses within one update, whatever the rooms' names
// (rooms_ is ordered by name, and "a-bulk" sorts first). Serial (one thread) and fork-join.
#include <gtest/gtest.h>

#include <map>
#include <memory>
#include <vector>

#include "protocol/testing/in_memory_network.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

// The relay's socket, recording where each datagram went and in which update.
class RecordingSocket final : public DatagramSocket {
 public:
  explicit RecordingSocket(DatagramSocket* inner) : inner_(inner) {}
  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override {
    sends.push_back({update, to});
    return inner_->SendTo(to, data);
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    return inner_->ReceiveFrom(from, buffer);
  }
  Endpoint LocalEndpoint() const override { return inner_->LocalEndpoint(); }
  struct Send {
    int update;
    Endpoint to;
  };
  std::vector<Send> sends;
  int update = 0;

 private:
  DatagramSocket* inner_;
};

class TickOrderTest : public ::testing::TestWithParam<size_t> {
 protected:
  void Run() {
    RelayConfig config = LoopbackWorld::DefaultConfig();
    config.physics_threads = GetParam();
    config.room_defaults.tick_rate_hz = 30;
    config.room_defaults.max_entities_per_player = 2000;
    config.limits.spawns_per_s = 0;
    config.limits.packets_per_s = 0;
    config.limits.bytes_per_s = 0;
    const Endpoint relay_at(asio::ip::make_address("10.0.0.1"), 7777);
    auto relay_raw = network_.CreateSocket(relay_at);
    RecordingSocket socket(relay_raw.get());
    RelayCounters counters;
    Relay relay(config, &socket, &counters);
    ClientConfig cc;
    cc.require_packet_auth = config.packet_auth;
    struct Member {
      std::unique_ptr<DatagramSocket> socket;
      std::unique_ptr<Client> client;
      std::string room;
      bool join_sent = false;
    };
    std::vector<Member> members;
    for (const char* room : {"a-bulk", "a-bulk", "b-light", "b-light"}) {
      Member m;
      m.room = room;
      m.socket = network_.CreateSocket(
          Endpoint(asio::ip::make_address("10.0.0.2"), static_cast<uint16_t>(20000 + members.size())));
      m.client = std::make_unique<Client>(cc, m.socket.get());
      ASSERT_TRUE(m.client->Connect(ToRelayAddress(relay_at),
                                    MintToken(room, static_cast<uint32_t>(members.size() + 1)), now_)
                      .ok());
      members.push_back(std::move(m));
    }
    auto step = [&](double dt) {
      now_ += dt;
      ++socket.update;
      relay.Update(now_, UnixNow());
      for (Member& m : members) {
        m.client->Update(now_);
        if (m.client->state() == ClientState::kConnected && !m.join_sent) {
          m.join_sent = m.client->JoinRoom(m.room).ok();
        }
      }
    };
    for (int i = 0; i < 400 && !(members[0].client->joined() && members[3].client->joined()); ++i) step(0.005);
    for (Member& m : members) ASSERT_TRUE(m.client->joined());
    // The bulk room: 1,100 entities from its first member; the light room: one hand each.
    std::vector<uint32_t> bulk, light;
    for (int i = 0; i < 1100; ++i) {
      auto id = members[0].client->Spawn({.position = {0.01f * i, 0, 0}});
      ASSERT_TRUE(id.ok());
      bulk.push_back(*id);
    }
    for (int k : {2, 3}) {
      auto id = members[k].client->Spawn({.position = {0, 1, 0}});
      ASSERT_TRUE(id.ok());
      light.push_back(*id);
    }
    for (int i = 0; i < 400 && members[1].client->entities().size() < bulk.size(); ++i) step(0.005);
    ASSERT_EQ(members[1].client->entities().size(), bulk.size());
    // Everything moves; steps of a whole tick interval, so both rooms tick in every update.
    const Endpoint bulk_receiver = members[1].socket->LocalEndpoint();
    const Endpoint light_receiver = members[3].socket->LocalEndpoint();
    int both = 0;
    for (int t = 1; t <= 30; ++t) {
      for (size_t i = 0; i < bulk.size(); ++i) {
        (void)members[0].client->PublishTransform(bulk[i], {0.01f * i, 0.001f * t, 0}, {});
      }
      (void)members[2].client->PublishTransform(light[0], {0.01f * t, 1, 0}, {});
      socket.sends.clear();
      step(1.0 / 30);
      // In this update: the first datagram to the light room's receiver must come before the
      // first to the bulk room's receiver.
      int first_bulk = -1, first_light = -1;
      for (size_t i = 0; i < socket.sends.size(); ++i) {
        if (socket.sends[i].to == bulk_receiver && first_bulk < 0) first_bulk = static_cast<int>(i);
        if (socket.sends[i].to == light_receiver && first_light < 0) first_light = static_cast<int>(i);
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
