// How often a soft body goes out (format 11, issue 15): at ReplicationConfig::soft_touched_hz
// while a Hand entity is within soft_touch_margin_m of one of its particles, else at normal_hz.
// A plate keeps a bunny squashed, so it moves (more than the 1 mm settle threshold) between
// any two sends and every due version is sent.
#include <gtest/gtest.h>

#include <algorithm>

#include "loadgen/scenes/scenes.h"
#include "tests/integration/harness.h"
#include "tests/integration/plated_bunny.h"

namespace edgephys::testing {
namespace {

using schema::EntityFlags;

struct SoftCount : ClientListener {
  uint32_t id = 0;
  int updates = 0;
  std::vector<Vec3f> nodes;
  void OnSoftBodyUpdated(const RemoteEntity& e) override {
    if (e.id != id) return;
    ++updates;
    nodes = e.nodes;
  }
};

TEST(SoftBodyRate, TouchedByAHandItGoesAtTheTouchedRateOtherwiseAtTheNormalRate) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.tick_rate_hz = 60;
  ReplicationConfig& rep = config.room_defaults.replication;
  ASSERT_EQ(rep.plugin, nullptr);
  ASSERT_EQ(rep.soft_touched_hz, 24);  // the default under test
  ASSERT_EQ(rep.normal_hz, 12);
  LoopbackWorld world(config);
  SoftCount count;
  PlatedBunny stage;
  ASSERT_NO_FATAL_FAILURE(StagePlatedBunny(world, "r", &count, &stage));
  Client& a = *stage.host;
  count.id = stage.bunny;
  float plate_y = stage.plate_y;
  // A hand with no collider (outside PhyS): only its position counts, 2 m away for now.
  SpawnDesc hand{.position = {2, 0.2f, 0}, .flags = static_cast<uint32_t>(EntityFlags::Hand),
                 .name = "hand"};
  auto hand_id = a.Spawn(hand);
  ASSERT_TRUE(hand_id.ok());
  ASSERT_TRUE(world.RunUntil([&] { return !count.nodes.empty(); }, 5.0));
  world.RunFor(1.5);  // landed
  float top = -1e9f;
  for (const Vec3f& q : count.nodes) top = std::max(top, q.y);
  const float target = 0.8f * top + 0.05f;
  const double lower_from = world.Now();
  auto hold = [&](double now, const Vec3f& hand_at) {
    plate_y = std::max(target, 1.5f - 0.3f * static_cast<float>(now - lower_from));
    (void)a.PublishTransform(stage.plate, {0, plate_y, 0}, {});
    (void)a.PublishTransform(*hand_id, hand_at, {});
  };
  world.RunFor(4.0, [&](double now) { hold(now, {2, 0.2f, 0}); });  // squashed, then held
  ASSERT_EQ(plate_y, target);

  const double window = 3.0;
  count.updates = 0;
  world.RunFor(window, [&](double now) { hold(now, {2, 0.2f, 0}); });
  const double far_hz = count.updates / window;
  // Now 5 cm beside the particle furthest along +x: within the 0.1 m margin.
  Vec3f side = count.nodes[0];
  for (const Vec3f& q : count.nodes) side = q.x > side.x ? q : side;
  side.x += 0.05f;
  world.RunFor(0.3, [&](double now) { hold(now, side); });
  count.updates = 0;
  world.RunFor(window, [&](double now) { hold(now, side); });
  const double near_hz = count.updates / window;
  std::printf("[soft rate] updates per second: hand 2 m away %.1f, hand 5 cm away %.1f\n", far_hz,
              near_hz);
  EXPECT_GE(far_hz, 0.75 * rep.normal_hz);
  EXPECT_LE(far_hz, 1.2 * rep.normal_hz);
  EXPECT_GE(near_hz, 0.75 * rep.soft_touched_hz);
  EXPECT_LE(near_hz, 1.2 * rep.soft_touched_hz);
}

}  // namespace
}  // namespace edgephys::testing
