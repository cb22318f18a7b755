// Ownership through the C API and its C++ wrapper against a real relay on loopback UDP: a hand
// over (OWNERSHIP_CHANGED to every member; the old owner can no longer publish, the new one
// can, and others see its states), a refused request (ERROR with TakeoverRefused), a granted
// one after takeover is allowed, release to the room, a locally simulated body offloaded to
// PhyS with its velocity and reclaimed with PhyS's (edgephys_client_offload,
// edgephys_client_get_owned_motion), and bad arguments refused before anything is sent.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <functional>
#include <string>
#include <vector>

#include "edgephys/edgephys.h"
#include "edgephys/edgephys.hpp"
#include "protocol/join_token.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

struct Member {
  sdk::Client* client;
  bool joined = false;
  std::vector<edgephys_event> changes, errors, states;
};

TEST(CApiOwnership, HandOverRequestTakeoverAndRelease) {
  LoopbackWorld world;
  edgephys_client_config cfg;
  ASSERT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
  cfg.bind_address = "127.0.0.1:0";
  cfg.queue_state_events = 1;
  sdk::Client a(&cfg), b(&cfg), c(&cfg);
  ASSERT_TRUE(a.ok() && b.ok() && c.ok());
  const std::string relay = "127.0.0.1:" + std::to_string(world.relay_endpoint().port());
  Member ma{&a}, mb{&b}, mc{&c};
  uint32_t player = 1;
  for (Member* m : {&ma, &mb, &mc}) {
    ASSERT_EQ(m->client->Connect(relay, Base64UrlEncode(MintToken("capi-own", player++)),
                                 world.Now()),
              EDGEPHYS_OK);
  }
  const auto pump = [&](const std::function<bool()>& done) {
    return world.RunUntil([&] {
      for (Member* m : {&ma, &mb, &mc}) {
        EXPECT_EQ(m->client->Update(world.Now()), EDGEPHYS_OK);
        edgephys_event ev;
        while (m->client->Poll(&ev)) {
          if (ev.type == EDGEPHYS_EVENT_CONNECTED) {
            EXPECT_EQ(m->client->Join("capi-own"), EDGEPHYS_OK);
          }
          if (ev.type == EDGEPHYS_EVENT_JOINED) m->joined = true;
          if (ev.type == EDGEPHYS_EVENT_OWNERSHIP_CHANGED) m->changes.push_back(ev);
          if (ev.type == EDGEPHYS_EVENT_ERROR) m->errors.push_back(ev);
          if (ev.type == EDGEPHYS_EVENT_STATE) m->states.push_back(ev);
        }
      }
      return done();
    }, 5.0);
  };
  ASSERT_TRUE(pump([&] { return ma.joined && mb.joined && mc.joined; }));
  edgephys_spawn_desc desc;
  ASSERT_EQ(edgephys_spawn_desc_init(&desc), EDGEPHYS_OK);
  const uint32_t id = a.Spawn(desc);
  ASSERT_NE(id, 0u) << sdk::Client::LastError();
  ASSERT_TRUE(pump([&] { return b.Owner(id) == 1 && c.Owner(id) == 1; }));
  EXPECT_EQ(a.Owner(id), 1u);

  // Refused while A forbids takeover.
  ASSERT_EQ(b.RequestOwnership(id), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] { return !mb.errors.empty(); }));
  EXPECT_EQ(mb.errors[0].code, static_cast<uint32_t>(EDGEPHYS_REJECT_TAKEOVER_REFUSED));
  EXPECT_EQ(mb.errors[0].entity_id, id);
  EXPECT_STREQ(edgephys_reason_name(EDGEPHYS_EVENT_ERROR, mb.errors[0].code), "TakeoverRefused");

  // Handed to B: every member hears it; B publishes, C sees B's pose.
  ASSERT_EQ(a.HandOver(id, 2), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] {
    return ma.changes.size() == 1 && mb.changes.size() == 1 && mc.changes.size() == 1;
  }));
  for (Member* m : {&ma, &mb, &mc}) {
    EXPECT_EQ(m->changes[0].entity_id, id);
    EXPECT_EQ(m->changes[0].player_id, 2u);
    EXPECT_EQ(m->changes[0].code, 1u);  // the authority sequence
  }
  edgephys_transform moved{{0.5f, 1.f, 0.f}, {0.f, 0.f, 0.f, 1.f}};
  EXPECT_EQ(a.Publish(id, moved), EDGEPHYS_E_NOT_FOUND);  // no longer A's
  ASSERT_EQ(b.Publish(id, moved), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] {
    for (const edgephys_event& s : mc.states) {
      if (s.entity_id == id && std::fabs(s.transform.position.x - 0.5f) < 0.002f && s.player_id == 2) return true;
    }
    return false;
  }));

  // Takeover allowed: A asks it back and gets it at once; then B may not release it.
  ASSERT_EQ(b.SetTakeoverAllowed(id, true), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] { return ma.changes.size() == 1; }));  // a setting: no event
  world.RunFor(0.1);
  ASSERT_EQ(a.RequestOwnership(id), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] { return c.Owner(id) == 1 && a.Owner(id) == 1 && b.Owner(id) == 1; }));
  EXPECT_EQ(b.ReleaseOwnership(id), EDGEPHYS_E_NOT_FOUND);
  // Released to the room.
  ASSERT_EQ(a.ReleaseOwnership(id), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] { return c.Owner(id) == 0 && mc.changes.size() == 3; }));
  EXPECT_EQ(mc.changes.back().code, 3u);
  EXPECT_EQ(mc.changes.back().player_id, 0u);

  // A dynamic body A simulates locally (PhyS mirrors it): offloaded with its velocity, PhyS
  // carries it on; C reclaims it and gets PhyS's pose and velocity.
  edgephys_rigid_body body;
  ASSERT_EQ(edgephys_rigid_body_init(&body), EDGEPHYS_OK);
  body.use_gravity = 0;
  edgephys_collider box;
  ASSERT_EQ(edgephys_collider_init(&box), EDGEPHYS_OK);
  box.half_extents = {0.1f, 0.1f, 0.1f};
  edgephys_spawn_desc moving;
  ASSERT_EQ(edgephys_spawn_desc_init(&moving), EDGEPHYS_OK);
  moving.transform.position = {0, 5, 0};
  moving.rigid_body = &body;
  moving.colliders = &box;
  moving.collider_count = 1;
  const uint32_t ball = a.Spawn(moving);
  ASSERT_NE(ball, 0u) << sdk::Client::LastError();
  ASSERT_TRUE(pump([&] { return c.Owner(ball) == 1; }));
  const edgephys_vec3 v{2.f, 0.f, 0.f};
  const edgephys_vec3 bad{std::nanf(""), 0.f, 0.f};
  EXPECT_EQ(edgephys_client_offload(a.handle(), ball, &bad, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  ASSERT_EQ(edgephys_client_offload(a.handle(), ball, &v, nullptr), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] { return c.Owner(ball) == 0 && a.Owner(ball) == 0; }));
  world.RunFor(0.2);
  ASSERT_EQ(c.RequestOwnership(ball), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] { return c.Owner(ball) == 3; }));
  edgephys_transform pose;
  edgephys_vec3 linear, angular;
  ASSERT_EQ(edgephys_client_get_owned_motion(c.handle(), ball, &pose, &linear, &angular), EDGEPHYS_OK);
  EXPECT_NEAR(linear.x, 2.f, 0.001f);
  EXPECT_NEAR(linear.y, 0.f, 0.001f);
  EXPECT_GT(pose.position.x, 0.1f);  // PhyS carried it along x
  EXPECT_NEAR(pose.position.y, 5.f, 0.001f);
  EXPECT_EQ(edgephys_client_get_owned_motion(a.handle(), ball, &pose, nullptr, nullptr),
            EDGEPHYS_E_NOT_FOUND);

  // Bad arguments: refused before anything is sent.
  EXPECT_EQ(a.RequestOwnership(0), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(a.RequestOwnership(0xdeadbeef), EDGEPHYS_E_NOT_FOUND);
  EXPECT_EQ(edgephys_client_set_takeover_allowed(a.handle(), id, 2), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_get_owner(a.handle(), id, nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_hand_over(nullptr, id, 2), EDGEPHYS_E_INVALID_HANDLE);
  EXPECT_EQ(ma.errors.size(), 0u);
  EXPECT_EQ(world.counters().ownership_changes.load(), 5u);

  // Leave choices: one chosen at spawn (stay), one changed by its owner (despawn), one from a
  // caller built against the header before on_owner_leave (its struct_size: default, despawn).
  edgephys_spawn_desc stays_desc;
  ASSERT_EQ(edgephys_spawn_desc_init(&stays_desc), EDGEPHYS_OK);
  stays_desc.on_owner_leave = 7;
  EXPECT_EQ(c.Spawn(stays_desc), 0u);  // an unknown choice
  stays_desc.on_owner_leave = EDGEPHYS_OWNER_LEAVE_STAY;
  const uint32_t stays = c.Spawn(stays_desc);
  edgephys_spawn_desc old_desc;
  ASSERT_EQ(edgephys_spawn_desc_init(&old_desc), EDGEPHYS_OK);
  old_desc.struct_size = offsetof(edgephys_spawn_desc, on_owner_leave);
  const uint32_t old = c.Spawn(old_desc);
  const uint32_t goes = c.Spawn(desc);
  ASSERT_TRUE(stays != 0 && old != 0 && goes != 0) << sdk::Client::LastError();
  EXPECT_EQ(c.SetOwnerLeave(goes, 9), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(a.SetOwnerLeave(goes, EDGEPHYS_OWNER_LEAVE_STAY), EDGEPHYS_E_NOT_FOUND);  // not A's
  ASSERT_EQ(c.SetOwnerLeave(goes, EDGEPHYS_OWNER_LEAVE_DESPAWN), EDGEPHYS_OK);
  ASSERT_TRUE(pump([&] { return a.Owner(stays) == 3 && a.Owner(old) == 3 && a.Owner(goes) == 3; }));
  ASSERT_EQ(c.Leave(), EDGEPHYS_OK);
  uint32_t owner = 99;
  ASSERT_TRUE(pump([&] {
    return a.Owner(stays) == 0 && b.Owner(stays) == 0 &&
           edgephys_client_get_owner(a.handle(), goes, &owner) == EDGEPHYS_E_NOT_FOUND &&
           edgephys_client_get_owner(a.handle(), old, &owner) == EDGEPHYS_E_NOT_FOUND;
  }));
}

}  // namespace
}  // namespace edgephys::testing
