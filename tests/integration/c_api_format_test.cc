// edgephys_client_get_state_format and EDGEPHYS_INTERP_AUTO against a real relay on loopback
// UDP: a receiver learns the room's state format (9, or 2 without shared encoding) from its
// Joined, and AUTO draws with Hermite in both; a format the SDK does not decode is refused and
// counted in edgephys_client_info.
#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <functional>
#include <string>

#include "client/interpolation.h"
#include "edgephys/edgephys.h"
#include "loadgen/emulation/emulation_plugins.h"
#include "protocol/join_token.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

RelayConfig Format2Config() {
  RelayConfig c = LoopbackWorld::DefaultConfig();
  c.room_defaults.replication.shared_encoding = false;  // format 2 rooms
  return c;
}

// Two C API clients in room "formats" of a relay with `config`; client 0 publishes `entity_`.
class CApiRoom : public ::testing::Test {
 protected:
  explicit CApiRoom(RelayConfig config) : world_(std::move(config)) {}

  void SetUp() override {
    for (int i = 0; i < 2; ++i) {
      edgephys_client_config cfg;
      ASSERT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
      cfg.bind_address = "127.0.0.1:0";
      cfg.publish_rate_hz = 60;
      ASSERT_EQ(edgephys_client_create(&cfg, &c_[i]), EDGEPHYS_OK) << edgephys_last_error();
      const std::string token = Base64UrlEncode(MintToken("formats", 11 + i));
      const std::string relay = "127.0.0.1:" + std::to_string(world_.relay_endpoint().port());
      ASSERT_EQ(edgephys_client_connect(c_[i], relay.c_str(), token.c_str(), world_.Now()),
                EDGEPHYS_OK)
          << edgephys_last_error();
    }
  }
  void TearDown() override {
    for (edgephys_client* c : c_) edgephys_client_destroy(c);
  }

  // A point on a circle of 0.3 m radius at 1.5 rad/s: curved, so Hermite and a line differ.
  static edgephys_transform On(double t) {
    return {{static_cast<float>(0.3 * std::cos(1.5 * t)), 1.0f, static_cast<float>(0.3 * std::sin(1.5 * t))},
            {0, 0, 0, 1}};
  }

  void Step() {
    world_.Step();
    const double now = world_.Now();
    for (int i = 0; i < 2; ++i) {
      ASSERT_EQ(edgephys_client_update(c_[i], now), EDGEPHYS_OK);
      edgephys_event ev;
      while (edgephys_client_poll_event(c_[i], &ev) == EDGEPHYS_OK && ev.type != EDGEPHYS_EVENT_NONE) {
        if (ev.type == EDGEPHYS_EVENT_CONNECTED) edgephys_client_join(c_[i], "formats");
        if (ev.type == EDGEPHYS_EVENT_JOINED) joined_[i] = true;
      }
    }
    if (entity_ != 0) {
      const edgephys_transform t = On(now);
      edgephys_client_publish_transform(c_[0], entity_, &t);
    }
  }
  bool RunUntil(const std::function<bool()>& done, double timeout_s) {
    const double end = world_.Now() + timeout_s;
    while (world_.Now() < end && !done()) Step();
    return done();
  }

  static double Distance(const edgephys_transform& a, const edgephys_transform& b) {
    const double dx = a.position.x - b.position.x, dy = a.position.y - b.position.y,
                 dz = a.position.z - b.position.z;
    return std::sqrt(dx * dx + dy * dy + dz * dz);
  }

  LoopbackWorld world_;
  edgephys_client* c_[2] = {nullptr, nullptr};
  bool joined_[2] = {false, false};
  uint32_t entity_ = 0;
};

class CApiFormat : public CApiRoom, public ::testing::WithParamInterface<bool> {  // a format-2 room
 protected:
  CApiFormat() : CApiRoom(GetParam() ? Format2Config() : LoopbackWorld::DefaultConfig()) {}
};

RelayConfig PhotonConfig() {
  RelayConfig c = LoopbackWorld::DefaultConfig();
  UseReplicationMode(ReplicationMode::kPhoton, &c.room_defaults.replication);
  return c;
}

class CApiRefusal : public CApiRoom {
 protected:
  CApiRefusal() : CApiRoom(PhotonConfig()) {}
};

// A relay sending an emulation's format (loadgen/emulation/, Photon-style format 3) to a C API
// client, which decodes none of it: every state payload is refused and counted in the info,
// nothing is applied, the client stays connected. A caller built before the counter (struct
// size 56) is still answered, and nothing is written past its struct.
TEST_F(CApiRefusal, StatesOfAFormatTheSdkDoesNotDecodeAreCountedInTheInfo) {
  ASSERT_TRUE(RunUntil([&] { return joined_[0] && joined_[1]; }, 5.0));
  uint32_t format = 0;
  ASSERT_EQ(edgephys_client_get_state_format(c_[1], &format), EDGEPHYS_OK);
  EXPECT_EQ(format, 3u);
  edgephys_spawn_desc d;
  ASSERT_EQ(edgephys_spawn_desc_init(&d), EDGEPHYS_OK);
  d.transform = On(world_.Now());
  ASSERT_EQ(edgephys_client_spawn(c_[0], &d, &entity_), EDGEPHYS_OK) << edgephys_last_error();
  edgephys_client_info info{};
  info.struct_size = sizeof(info);
  ASSERT_TRUE(RunUntil([&] {
    EXPECT_EQ(edgephys_client_get_info(c_[1], &info), EDGEPHYS_OK);
    return info.state_payloads_refused >= 20;
  }, 5.0)) << "refused " << info.state_payloads_refused;
  EXPECT_EQ(info.states_received, 0u);
  EXPECT_GT(info.state_bytes_received, 0u);
  EXPECT_EQ(info.state, static_cast<uint32_t>(EDGEPHYS_STATE_CONNECTED));
  EXPECT_EQ(info.joined, 1u);
  edgephys_transform t;
  EXPECT_NE(edgephys_client_sample_pose(c_[1], entity_, world_.Now(), EDGEPHYS_INTERP_AUTO, &t),
            EDGEPHYS_OK);

  constexpr uint32_t kOldSize = 56;
  static_assert(offsetof(edgephys_client_info, state_payloads_refused) == kOldSize);
  alignas(edgephys_client_info) unsigned char old[sizeof(edgephys_client_info)];
  std::memset(old, 0xCD, sizeof(old));
  std::memcpy(old, &kOldSize, sizeof(kOldSize));
  ASSERT_EQ(edgephys_client_get_info(c_[1], reinterpret_cast<edgephys_client_info*>(old)),
            EDGEPHYS_OK)
      << edgephys_last_error();
  for (size_t i = kOldSize; i < sizeof(old); ++i) EXPECT_EQ(old[i], 0xCD) << "byte " << i;
  info.struct_size = 60;
  EXPECT_EQ(edgephys_client_get_info(c_[1], &info), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_NE(std::string(edgephys_last_error()).find("state_payloads_refused"), std::string::npos)
      << edgephys_last_error();
}

TEST_P(CApiFormat, TheRoomsFormatReachesTheApiAndAutoDrawsWithWhatItCallsFor) {
  const bool format2 = GetParam();
  uint32_t format = 77;
  EXPECT_EQ(edgephys_client_get_state_format(c_[1], &format), EDGEPHYS_E_NOT_FOUND);
  EXPECT_EQ(format, 0u);  // before a Joined
  EXPECT_EQ(edgephys_client_get_state_format(c_[1], nullptr), EDGEPHYS_E_INVALID_ARGUMENT);
  EXPECT_EQ(edgephys_client_get_state_format(nullptr, &format), EDGEPHYS_E_INVALID_HANDLE);

  ASSERT_TRUE(RunUntil([&] { return joined_[0] && joined_[1]; }, 5.0));
  ASSERT_EQ(edgephys_client_get_state_format(c_[1], &format), EDGEPHYS_OK) << edgephys_last_error();
  EXPECT_EQ(format, format2 ? 2u : 9u);

  edgephys_spawn_desc d;
  ASSERT_EQ(edgephys_spawn_desc_init(&d), EDGEPHYS_OK);
  d.transform = On(world_.Now());
  ASSERT_EQ(edgephys_client_spawn(c_[0], &d, &entity_), EDGEPHYS_OK) << edgephys_last_error();
  edgephys_transform t;
  ASSERT_TRUE(RunUntil(
      [&] { return edgephys_client_sample_pose(c_[1], entity_, world_.Now(), EDGEPHYS_INTERP_AUTO, &t) == EDGEPHYS_OK; },
      5.0));
  EXPECT_EQ(edgephys_client_sample_pose(c_[1], entity_, world_.Now(), EDGEPHYS_INTERP_AUTO + 1, &t),
            EDGEPHYS_E_INVALID_ARGUMENT);

  // For 1.5 s of the circle: AUTO is, at every frame, exactly Hermite, and (the motion being
  // curved) lerp/slerp differs from it at some frames.
  const uint32_t wanted = EDGEPHYS_INTERP_HERMITE;
  const uint32_t other = EDGEPHYS_INTERP_LERP_SLERP;
  int frames = 0, differing = 0;
  const double end = world_.Now() + 1.5;
  while (world_.Now() < end) {
    Step();
    const double now = world_.Now();
    edgephys_transform a, w, o;
    ASSERT_EQ(edgephys_client_sample_pose(c_[1], entity_, now, EDGEPHYS_INTERP_AUTO, &a), EDGEPHYS_OK);
    ASSERT_EQ(edgephys_client_sample_pose(c_[1], entity_, now, wanted, &w), EDGEPHYS_OK);
    ASSERT_EQ(edgephys_client_sample_pose(c_[1], entity_, now, other, &o), EDGEPHYS_OK);
    ASSERT_EQ(Distance(a, w), 0.0) << "frame " << frames;
    ASSERT_EQ(a.rotation.w, w.rotation.w);
    ++frames;
    if (Distance(a, o) > 1e-5) ++differing;
  }
  EXPECT_GT(frames, 100);
  EXPECT_GT(differing, frames / 10) << "the other method should draw the circle differently";
}

// edgephys_client_set_max_playout_delay: a limit below the room's playout brings the delay of an
// entity already playing down to it (slewing), holds a new entity's from its first frame, and
// lifting it returns to the room's playout. Poses keep coming throughout.
TEST_P(CApiFormat, APlayoutLimitHoldsTheDelayOfPlayingAndNewEntities) {
  ASSERT_TRUE(RunUntil([&] { return joined_[0] && joined_[1]; }, 5.0));
  edgephys_spawn_desc d;
  ASSERT_EQ(edgephys_spawn_desc_init(&d), EDGEPHYS_OK);
  d.transform = On(world_.Now());
  ASSERT_EQ(edgephys_client_spawn(c_[0], &d, &entity_), EDGEPHYS_OK) << edgephys_last_error();
  edgephys_transform t;
  auto play = [&](uint32_t id, double seconds) {
    const double end = world_.Now() + seconds;
    while (world_.Now() < end) {
      Step();
      if (edgephys_client_sample_pose(c_[1], id, world_.Now(), EDGEPHYS_INTERP_AUTO, &t) != EDGEPHYS_OK) {
        return false;
      }
    }
    return true;
  };
  ASSERT_TRUE(RunUntil(
      [&] { return edgephys_client_sample_pose(c_[1], entity_, world_.Now(), EDGEPHYS_INTERP_AUTO, &t) == EDGEPHYS_OK; },
      5.0));
  ASSERT_TRUE(play(entity_, 2.0));
  double room = 0;
  ASSERT_EQ(edgephys_client_get_playout_delay(c_[1], entity_, &room), EDGEPHYS_OK) << edgephys_last_error();
  EXPECT_GT(room, 0.0);
  EXPECT_LE(room, SnapshotBufferConfig{}.max_delay_s + 1e-9);

  const double limit = room / 2;
  ASSERT_EQ(edgephys_client_set_max_playout_delay(c_[1], limit), EDGEPHYS_OK) << edgephys_last_error();
  ASSERT_TRUE(play(entity_, 3.0));
  double held = 0;
  ASSERT_EQ(edgephys_client_get_playout_delay(c_[1], entity_, &held), EDGEPHYS_OK);
  EXPECT_LE(held, limit + 1e-6);
  EXPECT_GT(held, limit / 2);

  // An entity first seen under the limit starts within it.
  uint32_t second = 0;
  d.transform = On(world_.Now());
  ASSERT_EQ(edgephys_client_spawn(c_[0], &d, &second), EDGEPHYS_OK) << edgephys_last_error();
  ASSERT_TRUE(RunUntil(
      [&] { return edgephys_client_sample_pose(c_[1], second, world_.Now(), EDGEPHYS_INTERP_AUTO, &t) == EDGEPHYS_OK; },
      5.0));
  double first = 0;
  ASSERT_EQ(edgephys_client_get_playout_delay(c_[1], second, &first), EDGEPHYS_OK);
  EXPECT_LE(first, limit + 1e-6);

  ASSERT_EQ(edgephys_client_set_max_playout_delay(c_[1], 0), EDGEPHYS_OK);
  ASSERT_TRUE(play(entity_, 3.0));
  double lifted = 0;
  ASSERT_EQ(edgephys_client_get_playout_delay(c_[1], entity_, &lifted), EDGEPHYS_OK);
  EXPECT_NEAR(lifted, room, room / 2);
}

INSTANTIATE_TEST_SUITE_P(Rooms, CApiFormat, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& p) {
                           return p.param ? std::string("Format2") : std::string("Default");
                         });

}  // namespace
}  // namespace edgephys::testing
