// Test fixture parts shared by tick_order_test.cc and room_work_test.cc: one relay with a bulk
// room "a-bulk" (more than Relay::kBulkRoomEntities entities) and a light room "b-light", on an
// InMemoryNetwork with a fake clock. Members 0 and 1 are in the bulk room (member 0 owns its
// 1,100 entities, member 1 receives them); members 2 and 3 are in the light room, one hand each.
#pragma once

#include <gtest/gtest.h>

#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "protocol/testing/in_memory_network.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {

struct BulkRoomsMember {
  std::unique_ptr<DatagramSocket> socket;
  std::unique_ptr<Client> client;
  std::string room;
  bool join_sent = false;

  // Updates the client; joins its room once connected.
  void Update(double now) {
    client->Update(now);
    if (client->state() == ClientState::kConnected && !join_sent) join_sent = client->JoinRoom(room).ok();
  }
};

// 30 Hz rooms, no spawn or packet limits, room for 2,000 entities per player.
inline RelayConfig BulkRoomsConfig(size_t physics_threads) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.physics_threads = physics_threads;
  config.room_defaults.tick_rate_hz = 30;
  config.room_defaults.max_entities_per_player = 2000;
  config.limits.spawns_per_s = 0;
  config.limits.packets_per_s = 0;
  config.limits.bytes_per_s = 0;
  return config;
}

// Connects the four members (bulk, bulk, light, light; "a-bulk" sorts first in the relay's
// rooms) to the relay at `relay_at`. Check HasFatalFailure() after the call.
inline void ConnectBulkRoomsMembers(InMemoryNetwork& network, const Endpoint& relay_at,
                                    const RelayConfig& config, double now,
                                    std::vector<BulkRoomsMember>* members) {
  ClientConfig cc;
  cc.require_packet_auth = config.packet_auth;
  for (const char* room : {"a-bulk", "a-bulk", "b-light", "b-light"}) {
    BulkRoomsMember m;
    m.room = room;
    m.socket = network.CreateSocket(Endpoint(asio::ip::make_address("10.0.0.2"),
                                             static_cast<uint16_t>(20000 + members->size())));
    m.client = std::make_unique<Client>(cc, m.socket.get());
    ASSERT_TRUE(m.client->Connect(ToRelayAddress(relay_at),
                                  MintToken(room, static_cast<uint32_t>(members->size() + 1)), now)
                    .ok());
    members->push_back(std::move(m));
  }
}

// Spawns the bulk room's 1,100 entities (member 0) and the light room's hands (members 2, 3),
// then steps (`step(dt)`, 5 ms at a time, at most 2 s) until member 1 holds all of the bulk
// room's. Check HasFatalFailure() after the call.
inline void SpawnBulkAndLight(std::vector<BulkRoomsMember>& members,
                              const std::function<void(double)>& step, std::vector<uint32_t>* bulk,
                              std::vector<uint32_t>* light) {
  for (int i = 0; i < 1100; ++i) {
    auto id = members[0].client->Spawn({.position = {0.01f * i, 0, 0}});
    ASSERT_TRUE(id.ok());
    bulk->push_back(*id);
  }
  for (int k : {2, 3}) {
    auto id = members[k].client->Spawn({.position = {0, 1, 0}});
    ASSERT_TRUE(id.ok());
    light->push_back(*id);
  }
  for (int i = 0; i < 400 && members[1].client->entities().size() < bulk->size(); ++i) step(0.005);
  ASSERT_EQ(members[1].client->entities().size(), bulk->size());
}

}  // namespace edgephys::testing
