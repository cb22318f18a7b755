// JoinAll: waits (simulated or real time, bounded at 10 s each) until every client is
// connected, joins each to `room`, and waits until each has joined. Fails the test otherwise.
#pragma once

#include <gtest/gtest.h>

#include <vector>

#include "client/client.h"

namespace edgephys::testing {

template <typename World>
void JoinAll(World& world, std::vector<Client*> clients, const char* room) {
  ASSERT_TRUE(world.RunUntil([&] {
    for (Client* c : clients) {
      if (c->state() != ClientState::kConnected) return false;
    }
    return true;
  }, 10.0));
  for (Client* c : clients) ASSERT_TRUE(c->JoinRoom(room).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    for (Client* c : clients) {
      if (!c->joined()) return false;
    }
    return true;
  }, 10.0));
}

}  // namespace edgephys::testing
