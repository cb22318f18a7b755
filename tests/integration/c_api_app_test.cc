// The application surface of the C API against a real relay on loopback UDP.
// Reasons: an operator's kick and room close reach the game as DISCONNECTED with the
// DisconnectReason and the operator's text; a refused token as REJECTED with its reason and a
// meaning; a refused command as ERROR with the relay's detail. edgephys_reason_name (and the
// C++ wrapper's ReasonName) names each code.
// Messages: edgephys_client_send_message to the room, the others and one player arrive as
// MESSAGE events with the sender's id and the payload (edgephys_client_get_message); unreliable
// ones (edgephys_client_send_message_unreliable) carry EDGEPHYS_MESSAGE_UNRELIABLE.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <functional>
#include <ostream>
#include <utility>
#include <string>
#include <vector>

#include "edgephys/edgephys.h"
#include "edgephys/edgephys.hpp"
#include "protocol/join_token.h"
#include "tests/integration/c_client_connect.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

// A C API client that keeps every event and the application messages it got.
class CClient : public CClientBase {
 public:
  using CClientBase::CClientBase;

  const edgephys_event* Find(uint32_t type) const {
    for (const auto& e : events) {
      if (e.type == type) return &e;
    }
    return nullptr;
  }

  std::vector<edgephys_event> events;
  std::vector<std::pair<uint32_t, std::string>> messages;  // sender, payload

 private:
  void OnEvent(const edgephys_event& ev) override {
    if (ev.type == EDGEPHYS_EVENT_MESSAGE) {
      std::vector<uint8_t> payload(ev.code);
      size_t n = 0;
      EXPECT_EQ(edgephys_client_get_message(c, payload.data(), payload.size(), &n), EDGEPHYS_OK);
      EXPECT_EQ(n, payload.size());
      messages.push_back({ev.player_id, std::string(payload.begin(), payload.end())});
    }
    events.push_back(ev);
  }
};

// Pumps `watched` and `others` (joining nothing) until `watched` has an event of `type`, for at
// most 5 s; returns that event, or nullptr when none came.
const edgephys_event* AwaitEvent(LoopbackWorld& world, CClient& watched, uint32_t type,
                                 std::vector<CClientBase*> others = {}) {
  others.insert(others.begin(), &watched);
  if (!Pump(world, others, nullptr, [&] { return watched.Find(type) != nullptr; }, 5.0)) {
    return nullptr;
  }
  return watched.Find(type);
}

TEST(CApiReasons, AKickArrivesWithItsReasonAndTheOperatorsText) {
  LoopbackWorld world;
  CClient a(world, MintToken("ward", 1)), b(world, MintToken("ward", 2));
  ASSERT_TRUE(Pump(world, {&a, &b}, "ward", [&] { return a.joined && b.joined; }, 5.0));
  ASSERT_TRUE(world.relay().Kick("ward", 1, "abusive chat, 10 minute ban", world.Now()).ok());
  const edgephys_event* ev = AwaitEvent(world, a, EDGEPHYS_EVENT_DISCONNECTED, {&b});
  ASSERT_NE(ev, nullptr);
  EXPECT_EQ(ev->code, static_cast<uint32_t>(EDGEPHYS_DISCONNECT_KICKED));
  EXPECT_STREQ(ev->detail, "abusive chat, 10 minute ban");
  EXPECT_STREQ(edgephys_reason_name(ev->type, ev->code), "Kicked");
  EXPECT_STREQ(sdk::ReasonName(*ev), "Kicked");  // the C++ wrapper's
  EXPECT_EQ(b.Find(EDGEPHYS_EVENT_DISCONNECTED), nullptr);  // only the kicked player
  edgephys_client_info info{};
  info.struct_size = sizeof(info);
  ASSERT_EQ(edgephys_client_get_info(a.c, &info), EDGEPHYS_OK);
  EXPECT_EQ(info.disconnect_reason, static_cast<uint32_t>(EDGEPHYS_DISCONNECT_KICKED));
}

TEST(CApiReasons, ARoomCloseReachesEveryMemberWithTheText) {
  LoopbackWorld world;
  CClient a(world, MintToken("lab", 1)), b(world, MintToken("lab", 2));
  ASSERT_TRUE(Pump(world, {&a, &b}, "lab", [&] { return a.joined && b.joined; }, 5.0));
  ASSERT_TRUE(world.relay().CloseRoom("lab", "session over", world.Now()).ok());
  ASSERT_TRUE(Pump(world, {&a, &b}, nullptr,
                   [&] {
                     return a.Find(EDGEPHYS_EVENT_DISCONNECTED) != nullptr &&
                            b.Find(EDGEPHYS_EVENT_DISCONNECTED) != nullptr;
                   },
                   5.0));
  for (CClient* c : {&a, &b}) {
    const edgephys_event* ev = c->Find(EDGEPHYS_EVENT_DISCONNECTED);
    EXPECT_EQ(ev->code, static_cast<uint32_t>(EDGEPHYS_DISCONNECT_KICKED));
    EXPECT_STREQ(ev->detail, "session over");
  }
}

// The relay ends a lone player's session: the game gets DISCONNECTED with the reason, its name
// and the operator's text, or the reason's meaning when there was none.
struct LoneDisconnect {
  const char* name;
  const char* room;
  std::function<void(LoopbackWorld&)> end;  // what the relay does, the player being joined
  edgephys_disconnect_reason reason;
  const char* reason_name;
  const char* detail;  // nullptr: no text given, the detail is the reason's meaning
};
void PrintTo(const LoneDisconnect& k, std::ostream* os) { *os << k.name; }

class CApiLoneDisconnect : public ::testing::TestWithParam<LoneDisconnect> {};

TEST_P(CApiLoneDisconnect, ReachesTheGameWithItsReasonAndText) {
  const LoneDisconnect& k = GetParam();
  LoopbackWorld world;
  CClient a(world, MintToken(k.room, 1));
  ASSERT_TRUE(Pump(world, {&a}, k.room, [&] { return a.joined; }, 5.0));
  ASSERT_NO_FATAL_FAILURE(k.end(world));
  const edgephys_event* ev = AwaitEvent(world, a, EDGEPHYS_EVENT_DISCONNECTED);
  ASSERT_NE(ev, nullptr);
  EXPECT_EQ(ev->code, static_cast<uint32_t>(k.reason));
  EXPECT_STREQ(edgephys_reason_name(ev->type, ev->code), k.reason_name);
  if (k.detail != nullptr) {
    EXPECT_STREQ(ev->detail, k.detail);
  } else {
    EXPECT_STRNE(ev->detail, "");
  }
}

INSTANTIATE_TEST_SUITE_P(
    CApiReasons, CApiLoneDisconnect,
    ::testing::Values(
        LoneDisconnect{"AKickWithoutTextCarriesTheReasonsMeaning", "quiet",
                       [](LoopbackWorld& world) {
                         ASSERT_TRUE(world.relay().Kick("quiet", 1, "", world.Now()).ok());
                       },
                       EDGEPHYS_DISCONNECT_KICKED, "Kicked", nullptr},
        LoneDisconnect{"ADrainReachesTheGameAsServerShutdownWithTheText", "ward",
                       [](LoopbackWorld& world) {
                         world.relay().CloseAllSessions("maintenance at 02:00 UTC", world.Now());
                       },
                       EDGEPHYS_DISCONNECT_SERVER_SHUTDOWN, "ServerShutdown",
                       "maintenance at 02:00 UTC"}),
    [](const ::testing::TestParamInfo<LoneDisconnect>& param_info) {
      return std::string(param_info.param.name);
    });

TEST(CApiReasons, ABadTokenIsRejectedWithItsReasonAndMeaning) {
  LoopbackWorld world;
  JoinToken t;
  t.room = "ward";
  t.player_id = 3;
  t.permissions = kDefaultPermissions;
  t.expiry_unix_s = UnixNow() + 3600;
  t.nonce = SecureRandom64();
  CClient a(world, *SignJoinToken(t, "not-the-relays-secret"));
  ASSERT_TRUE(Pump(world, {&a}, "ward",
                   [&] { return a.Find(EDGEPHYS_EVENT_REJECTED) != nullptr; }, 5.0));
  const edgephys_event* ev = a.Find(EDGEPHYS_EVENT_REJECTED);
  EXPECT_EQ(ev->code, static_cast<uint32_t>(EDGEPHYS_REJECT_BAD_TOKEN));
  EXPECT_STREQ(edgephys_reason_name(ev->type, ev->code), "BadToken");
  EXPECT_NE(std::strstr(ev->detail, "token"), nullptr) << ev->detail;
}

TEST(CApiReasons, ARefusedCommandIsAnErrorWithReasonAndDetail) {
  LoopbackWorld world;
  CClient a(world, MintToken("ward", 1));
  ASSERT_TRUE(Pump(world, {&a}, "ward", [&] { return a.joined; }, 5.0));
  // Grab an entity the room does not hold.
  ASSERT_EQ(edgephys_client_grab(a.c, 424242, 1), EDGEPHYS_OK) << edgephys_last_error();
  const edgephys_event* ev = AwaitEvent(world, a, EDGEPHYS_EVENT_ERROR);
  ASSERT_NE(ev, nullptr);
  EXPECT_NE(ev->code, 0u);
  EXPECT_STRNE(edgephys_reason_name(ev->type, ev->code), "unknown");
  EXPECT_STRNE(ev->detail, "") << edgephys_reason_name(ev->type, ev->code);
}

TEST(CApiMessages, ReachTheAddressedPlayersWithTheSendersIdAndPayload) {
  LoopbackWorld world;
  CClient a(world, MintToken("chat", 1)), b(world, MintToken("chat", 2)),
      c(world, MintToken("chat", 3));
  ASSERT_TRUE(Pump(world, {&a, &b, &c}, "chat",
                   [&] { return a.joined && b.joined && c.joined; }, 5.0));
  const std::string line = "hello from 1";
  const std::string big(50000, 'x');
  ASSERT_EQ(edgephys_client_send_message(a.c, EDGEPHYS_TO_ROOM, 0, line.data(), line.size()),
            EDGEPHYS_OK);
  ASSERT_EQ(edgephys_client_send_message(a.c, EDGEPHYS_TO_OTHERS, 0, big.data(), big.size()),
            EDGEPHYS_OK);
  ASSERT_EQ(edgephys_client_send_message(b.c, EDGEPHYS_TO_PLAYER, 3, "psst", 4), EDGEPHYS_OK);
  // Refused before sending: too large, unknown target, a player target of 0, NULL data.
  std::vector<char> huge(EDGEPHYS_MAX_MESSAGE_BYTES + 1);
  EXPECT_EQ(edgephys_client_send_message(a.c, EDGEPHYS_TO_ROOM, 0, huge.data(), huge.size()),
            EDGEPHYS_E_TOO_LARGE);
  EXPECT_EQ(edgephys_client_send_message(a.c, 3, 0, "x", 1), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_send_message(a.c, EDGEPHYS_TO_PLAYER, 0, "x", 1),
            EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_send_message(a.c, EDGEPHYS_TO_ROOM, 0, nullptr, 1),
            EDGEPHYS_E_INVALID_ARGUMENT);
  // Refused by the relay: a player not in the room.
  ASSERT_EQ(edgephys_client_send_message(a.c, EDGEPHYS_TO_PLAYER, 77, "?", 1), EDGEPHYS_OK);
  ASSERT_TRUE(Pump(world, {&a, &b, &c}, nullptr,
                   [&] {
                     return a.messages.size() >= 1 && b.messages.size() >= 2 &&
                            c.messages.size() >= 3 && a.Find(EDGEPHYS_EVENT_ERROR) != nullptr;
                   },
                   5.0));
  world.RunFor(0.3);
  // Order holds per sender (different senders' messages may interleave either way).
  using M = std::vector<std::pair<uint32_t, std::string>>;
  const auto by_sender = [](M m) {
    std::stable_sort(m.begin(), m.end(), [](const auto& x, const auto& y) { return x.first < y.first; });
    return m;
  };
  EXPECT_EQ(a.messages, (M{{1, line}}));
  EXPECT_EQ(b.messages, (M{{1, line}, {1, big}}));
  EXPECT_EQ(by_sender(c.messages), (M{{1, line}, {1, big}, {2, "psst"}}));
  const edgephys_event* err = a.Find(EDGEPHYS_EVENT_ERROR);
  EXPECT_EQ(err->code, static_cast<uint32_t>(EDGEPHYS_REJECT_UNKNOWN_PLAYER));
  EXPECT_STREQ(edgephys_reason_name(err->type, err->code), "UnknownPlayer");
  // After a non-MESSAGE poll there is no payload to read.
  size_t n = 0;
  EXPECT_EQ(edgephys_client_get_message(a.c, nullptr, 0, &n), EDGEPHYS_E_NOT_FOUND);
}

// Unreliable messages: edgephys_client_send_message_unreliable arrives as a MESSAGE event with
// EDGEPHYS_MESSAGE_UNRELIABLE in its flags; over one datagram it is refused naming the limit.
TEST(CApiMessages, UnreliableArriveFlaggedAndTheOversizedAreRefused) {
  LoopbackWorld world;
  CClient a(world, MintToken("chat", 1)), b(world, MintToken("chat", 2));
  ASSERT_TRUE(Pump(world, {&a, &b}, "chat", [&] { return a.joined && b.joined; }, 5.0));
  world.RunFor(0.3);  // both have acknowledged their Joined
  const std::string ray(EDGEPHYS_MAX_UNRELIABLE_MESSAGE_BYTES, 'r');
  ASSERT_EQ(edgephys_client_send_message_unreliable(a.c, EDGEPHYS_TO_OTHERS, 0, ray.data(),
                                                    ray.size()),
            EDGEPHYS_OK);
  std::vector<char> huge(EDGEPHYS_MAX_UNRELIABLE_MESSAGE_BYTES + 1);
  EXPECT_EQ(edgephys_client_send_message_unreliable(a.c, EDGEPHYS_TO_ROOM, 0, huge.data(),
                                                    huge.size()),
            EDGEPHYS_E_TOO_LARGE);
  EXPECT_NE(std::string(edgephys_last_error()).find("EDGEPHYS_MAX_UNRELIABLE_MESSAGE_BYTES"),
            std::string::npos);
  EXPECT_EQ(edgephys_client_send_message_unreliable(a.c, 3, 0, "x", 1),
            EDGEPHYS_E_INVALID_ARGUMENT);
  ASSERT_EQ(edgephys_client_send_message(a.c, EDGEPHYS_TO_OTHERS, 0, "reliable", 8), EDGEPHYS_OK);
  ASSERT_TRUE(Pump(world, {&a, &b}, nullptr, [&] { return b.messages.size() >= 2; }, 5.0));
  world.RunFor(0.2);
  ASSERT_EQ(b.messages.size(), 2u);
  EXPECT_TRUE(a.messages.empty());
  for (const edgephys_event& e : b.events) {
    if (e.type != EDGEPHYS_EVENT_MESSAGE) continue;
    const bool unreliable = (e.flags & EDGEPHYS_MESSAGE_UNRELIABLE) != 0;
    EXPECT_EQ(e.player_id, 1u);
    EXPECT_EQ(unreliable, e.code == ray.size()) << e.code;
  }
}

// Scenery: a box offloaded to PhyS above a static ground made with edgephys_client_spawn_static
// comes to rest on it (without the ground it would fall until the guard resets it).
TEST(CApiScenery, AnOffloadedBoxRestsOnStaticGround) {
  LoopbackWorld world;
  CClient a(world, MintToken("scene", 1));
  ASSERT_TRUE(Pump(world, {&a}, "scene", [&] { return a.joined; }, 5.0));
  edgephys_collider ground;
  ASSERT_EQ(edgephys_collider_init(&ground), EDGEPHYS_OK);
  ground.half_extents = {5, 0.5f, 5};
  const edgephys_transform at{{0, -0.5f, 0}, {0, 0, 0, 1}};
  uint32_t ground_id = 0;
  ASSERT_EQ(edgephys_client_spawn_static(a.c, &at, &ground, 1, "ground", &ground_id),
            EDGEPHYS_OK)
      << edgephys_last_error();
  EXPECT_EQ(edgephys_client_spawn_static(a.c, &at, &ground, 0, "none", &ground_id),
            EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_spawn_static(a.c, &at, nullptr, 1, "none", &ground_id),
            EDGEPHYS_E_INVALID_ARGUMENT);
  edgephys_collider cube;
  ASSERT_EQ(edgephys_collider_init(&cube), EDGEPHYS_OK);
  cube.half_extents = {0.25f, 0.25f, 0.25f};
  edgephys_rigid_body body;
  ASSERT_EQ(edgephys_rigid_body_init(&body), EDGEPHYS_OK);
  edgephys_spawn_desc d;
  ASSERT_EQ(edgephys_spawn_desc_init(&d), EDGEPHYS_OK);
  d.transform.position.y = 1.0f;
  d.flags = EDGEPHYS_FLAG_OFFLOADED;
  d.rigid_body = &body;
  d.colliders = &cube;
  d.collider_count = 1;
  uint32_t box = 0;
  ASSERT_EQ(edgephys_client_spawn(a.c, &d, &box), EDGEPHYS_OK) << edgephys_last_error();
  edgephys_entity e{};
  const bool rested = Pump(world, {&a}, nullptr, [&] {
    if (edgephys_client_get_entity(a.c, box, &e) != EDGEPHYS_OK || e.has_state == 0) return false;
    return std::fabs(e.transform.position.y - 0.25f) < 0.02f;
  }, 8.0);
  EXPECT_TRUE(rested) << "box at y " << e.transform.position.y;
  EXPECT_EQ(a.Find(EDGEPHYS_EVENT_ERROR), nullptr);
  world.RunFor(0.5);
  for (int i = 0; i < 5; ++i) a.Update(nullptr);
  ASSERT_EQ(edgephys_client_get_entity(a.c, box, &e), EDGEPHYS_OK);
  EXPECT_NEAR(e.transform.position.y, 0.25f, 0.02f);  // still resting, not sinking
}

}  // namespace
}  // namespace edgephys::testing
