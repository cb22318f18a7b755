#include "physics/box_pair_prefilter.h"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <cstring>
#include <vector>

#include "physics/physics_test_util.h"
#include "physics/scenes.h"

namespace edgephys::physics {
namespace {

using testing::Add;

btCollisionDispatcher* Dispatcher(PhysicsWorld& w) {
  return static_cast<btCollisionDispatcher*>(w.BulletWorldForTesting()->getDispatcher());
}

// Box-box pairs in the broadphase that are certainly disjoint: the pairs the prefilter skips in
// the next step.
int SkippablePairs(PhysicsWorld& w) {
  btOverlappingPairCache* cache =
      w.BulletWorldForTesting()->getBroadphase()->getOverlappingPairCache();
  btBroadphasePairArray& pairs = cache->getOverlappingPairArray();
  int n = 0;
  for (int i = 0; i < pairs.size(); ++i) {
    const auto* o0 = static_cast<const btCollisionObject*>(pairs[i].m_pProxy0->m_clientObject);
    const auto* o1 = static_cast<const btCollisionObject*>(pairs[i].m_pProxy1->m_clientObject);
    if (o0->getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE ||
        o1->getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE) {
      continue;
    }
    if (internal::BoxesCannotTouch(*o0, *o1)) ++n;
  }
  return n;
}

bool SameBits(const std::vector<EntityState>& a, const std::vector<EntityState>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].entity_id != b[i].entity_id ||
        std::memcmp(&a[i].position, &b[i].position, sizeof(a[i].position)) != 0 ||
        std::memcmp(&a[i].rotation, &b[i].rotation, sizeof(a[i].rotation)) != 0) {
      return false;
    }
  }
  return true;
}

bool SameEvents(const std::vector<PhysicsEvent>& a, const std::vector<PhysicsEvent>& b) {
  if (a.size() != b.size()) return false;
  for (size_t i = 0; i < a.size(); ++i) {
    if (a[i].type != b[i].type || a[i].cause != b[i].cause || a[i].entity_a != b[i].entity_a ||
        a[i].entity_b != b[i].entity_b || a[i].step != b[i].step) {
      return false;
    }
  }
  return true;
}

// The stirred pile at PhyS's defaults, once with the prefilter (installed by PhysicsWorld) and
// once with Bullet's own near callback: every step's moved states and events, and the final
// velocities, are bit-identical, while the prefilter had pairs to skip on most steps.
TEST(BoxPairPrefilterTest, StirredPileIsBitIdenticalToBulletsNearCallback) {
  MultiObjectParams p;
  p.num_objects = 300;
  PhysicsWorld filtered(p.config);
  PhysicsWorld bullet(p.config);
  for (const EntitySpec& spec : MultiObjectSpecs(p)) {
    ASSERT_TRUE(Add(filtered, spec).ok());
    ASSERT_TRUE(Add(bullet, spec).ok());
  }
  ASSERT_EQ(Dispatcher(filtered)->getNearCallback(), &internal::BoxPairPrefilterNearCallback);
  Dispatcher(bullet)->setNearCallback(btCollisionDispatcher::defaultNearCallback);

  std::vector<EntityState> moved_f, moved_b;
  std::vector<PhysicsEvent> events_f, events_b;
  long skippable = 0;
  int steps_with_skips = 0;
  size_t events = 0;
  const int kSteps = 420;  // 7 s: drop, settle, stir
  for (int step = 1; step <= kSteps; ++step) {
    Vec3f pos;
    Quatf rot;
    StirrerPose(p, static_cast<double>(step) * p.config.fixed_dt, &pos, &rot);
    ASSERT_TRUE(filtered.MoveToTransform(kSceneStirrerId, pos, rot).ok());
    ASSERT_TRUE(bullet.MoveToTransform(kSceneStirrerId, pos, rot).ok());
    const int skip = SkippablePairs(filtered);
    skippable += skip;
    if (skip > 0) ++steps_with_skips;
    filtered.Step();
    bullet.Step();
    filtered.CollectStates(&moved_f);
    bullet.CollectStates(&moved_b);
    events_f.clear();
    events_b.clear();
    filtered.DrainEvents(&events_f);
    bullet.DrainEvents(&events_b);
    events += events_f.size();
    ASSERT_TRUE(SameBits(moved_f, moved_b)) << "states differ at step " << step;
    ASSERT_TRUE(SameEvents(events_f, events_b)) << "events differ at step " << step;
  }
  for (int i = 0; i < p.num_objects; ++i) {
    const uint32_t id = kSceneFirstBoxId + static_cast<uint32_t>(i);
    Vec3f lf, af, lb, ab;
    ASSERT_TRUE(filtered.GetVelocity(id, &lf, &af).ok());
    ASSERT_TRUE(bullet.GetVelocity(id, &lb, &ab).ok());
    EXPECT_EQ(std::memcmp(&lf, &lb, sizeof(lf)), 0) << id;
    EXPECT_EQ(std::memcmp(&af, &ab, sizeof(af)), 0) << id;
  }
  std::printf("[prefilter N=300, %d steps] skippable pairs %ld (%d steps with some), events %zu\n",
              kSteps, skippable, steps_with_skips, events);
  // The comparison means something only if the prefilter took its skip path often.
  EXPECT_GT(steps_with_skips, kSteps / 2);
  EXPECT_GT(events, 1000u);
  EXPECT_GT(filtered.counters().rest_wakes + filtered.counters().frozen_bodies, 0u);
}

// Manifold reuse replaces Bullet's box-box algorithm, so the prefilter stays out of it.
TEST(BoxPairPrefilterTest, NotInstalledWithManifoldReuse) {
  PhysicsConfig cfg;
  cfg.manifold_reuse_distance = 0.001f;
  PhysicsWorld w(cfg);
  EXPECT_NE(Dispatcher(w)->getNearCallback(), &internal::BoxPairPrefilterNearCallback);
}

}  // namespace
}  // namespace edgephys::physics
