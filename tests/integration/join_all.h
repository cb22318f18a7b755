// JoinAll: waits (simulated or real time, bounded at 10 s each) until every client is
// connected, joins each to `room`, and waits until each has joined. Fails the test otherwise.
// AddJoined: adds the room's first joiners to a world and joins them (JoinAll).
#pragma once

#include <gtest/gtest.h>

#include <cstdint>
#include <tuple>
#include <vector>

#include "client/client.h"
#include "tests/integration/harness.h"

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

// One joiner for AddJoined: the client's listener and the permissions its token grants.
struct Joiner {
  ClientListener* listener;
  uint32_t permissions = kDefaultPermissions;
};
inline Joiner AsJoiner(ClientListener& listener) { return Joiner{&listener}; }
inline Joiner AsJoiner(const Joiner& member) { return member; }

template <typename T>
using ClientRef = Client&;

// Adds one client to `world` per joiner, as players 1, 2, ... of `room` (a MintToken token
// with the joiner's permissions, default ones for a bare listener), then JoinAll's them.
// Returns the clients in joiner order: `auto [a, b] = AddJoined(world, "r", ia, ib);`.
// A join that does not finish fails the test (as JoinAll does).
template <typename World, typename... Joiners>
std::tuple<ClientRef<Joiners>...> AddJoined(World& world, const char* room, Joiners&&... joiners) {
  uint32_t player = 0;
  auto add = [&](const Joiner& m) -> Client& {
    return world.AddClient(MintToken(room, ++player, 3600, m.permissions), m.listener);
  };
  // A braced list is evaluated in order: players are numbered in joiner order.
  std::tuple<ClientRef<Joiners>...> clients{add(AsJoiner(joiners))...};
  std::apply([&](auto&... c) { JoinAll(world, {&c...}, room); }, clients);
  return clients;
}

}  // namespace edgephys::testing
