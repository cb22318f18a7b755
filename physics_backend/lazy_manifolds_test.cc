// Box-box manifolds only for touching pairs (PhysicsConfig::lazy_box_manifolds,
// physics/lazy_manifolds.h): no manifold for a pair that does not touch, Bullet's points for one
// that does, release after the keep time, contact events exactly once, and a stirred pile stays
// in its container. Speed is measured in bench/physics_cost_report.cc, not here.
#include <gtest/gtest.h>

#include <btBulletDynamicsCommon.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

#include "physics_backend/lazy_manifolds.h"
#include "physics_backend/physics_test_util.h"
#include "physics_backend/scenes.h"

namespace edgephys::physics {
namespace {

using testing::Add;
using testing::Ground;
using testing::Pos;

// Two boxes in a bare btCollisionWorld, box-box pairs handled by Bullet's algorithm or by the
// lazy one; only collision detection (no dynamics), so both see exactly the same poses.
class Pair {
 public:
  explicit Pair(bool lazy, int keep_steps = 2)
      : dispatcher_(&config_), world_(&dispatcher_, &broadphase_, &config_),
        lazy_(keep_steps, (dispatcher_.getDispatcherFlags() &
                           btCollisionDispatcher::CD_USE_RELATIVE_CONTACT_BREAKING_THRESHOLD) != 0) {
    if (lazy) dispatcher_.registerCollisionCreateFunc(BOX_SHAPE_PROXYTYPE, BOX_SHAPE_PROXYTYPE, &lazy_);
    for (int i = 0; i < 2; ++i) {
      objects_[i].setCollisionShape(&shapes_[i]);
      world_.addCollisionObject(&objects_[i]);
    }
  }
  ~Pair() {
    for (int i = 0; i < 2; ++i) world_.removeCollisionObject(&objects_[i]);
  }
  // Box 1 at `p1` rotated by `angle` about (1, 1, 0); box 0 at the origin. Runs the narrowphase.
  void Detect(const btVector3& p1, btScalar angle) {
    btTransform t1(btQuaternion(btVector3(1, 1, 0).normalized(), angle), p1);
    objects_[0].setWorldTransform(btTransform::getIdentity());
    objects_[1].setWorldTransform(t1);
    world_.performDiscreteCollisionDetection();
  }
  int manifolds() const { return dispatcher_.getNumManifolds(); }
  int pairs() { return world_.getPairCache()->getNumOverlappingPairs(); }
  const btPersistentManifold* manifold() const {
    return manifolds() > 0 ? dispatcher_.getManifoldByIndexInternal(0) : nullptr;
  }
  const LazyManifoldStats& stats() const { return lazy_.stats(); }

 private:
  btDefaultCollisionConfiguration config_;
  btCollisionDispatcher dispatcher_;
  btDbvtBroadphase broadphase_;
  btCollisionWorld world_;
  LazyBoxBoxCreateFunc lazy_;
  btBoxShape shapes_[2] = {btBoxShape(btVector3(0.1f, 0.1f, 0.1f)),
                           btBoxShape(btVector3(0.2f, 0.05f, 0.1f))};
  btCollisionObject objects_[2];
};

// Same points (positions, normals, depths, in the same slots) in both manifolds.
void ExpectSamePoints(const btPersistentManifold* lazy, const btPersistentManifold* bullet) {
  ASSERT_NE(lazy, nullptr);
  ASSERT_NE(bullet, nullptr);
  ASSERT_EQ(lazy->getNumContacts(), bullet->getNumContacts());
  for (int i = 0; i < lazy->getNumContacts(); ++i) {
    const btManifoldPoint& a = lazy->getContactPoint(i);
    const btManifoldPoint& b = bullet->getContactPoint(i);
    EXPECT_EQ(a.m_positionWorldOnA, b.m_positionWorldOnA) << i;
    EXPECT_EQ(a.m_positionWorldOnB, b.m_positionWorldOnB) << i;
    EXPECT_EQ(a.m_normalWorldOnB, b.m_normalWorldOnB) << i;
    EXPECT_EQ(a.m_localPointA, b.m_localPointA) << i;
    EXPECT_EQ(a.getDistance(), b.getDistance()) << i;
    EXPECT_EQ(a.getLifeTime(), b.getLifeTime()) << i;
  }
}

// One path through apart -> touching (face and tilted) -> apart, with Bullet's algorithm and the
// lazy one on the same poses: no manifold while apart, the same points while touching, and the
// empty manifold released after keep_steps + 1 steps (Bullet keeps its empty one).
TEST(LazyManifoldsTest, ManifoldOnlyWhileTouchingWithBulletsPoints) {
  const int keep = 2;
  Pair lazy(true, keep);
  Pair bullet(false);
  // Box 0's top face at y = 0.1, box 1 (half height 0.05) above it.
  auto both = [&](float gap, btScalar angle, btScalar x) {
    const btVector3 p(x, 0.1f + 0.05f + gap, 0.02f);
    lazy.Detect(p, angle);
    bullet.Detect(p, angle);
  };
  // Apart, within the broadphase's reach: a pair, no manifold (Bullet: an empty one).
  both(0.01f, 0, 0);
  ASSERT_EQ(lazy.pairs(), 1);
  EXPECT_EQ(lazy.manifolds(), 0);
  EXPECT_EQ(bullet.manifolds(), 1);
  EXPECT_EQ(bullet.manifold()->getNumContacts(), 0);
  EXPECT_EQ(lazy.stats().created, 0u);
  // Touching: 2 mm deep, then sliding and tilting; points kept persistently as Bullet does.
  const float xs[] = {0, 0.003f, 0.006f, 0.009f, 0.012f};
  const btScalar angles[] = {0, 0, 0.01f, 0.02f, 0.04f};
  for (int s = 0; s < 5; ++s) {
    both(-0.002f, angles[s], xs[s]);
    ASSERT_EQ(lazy.manifolds(), 1) << s;
    ASSERT_GT(lazy.manifold()->getNumContacts(), 0) << s;
    ExpectSamePoints(lazy.manifold(), bullet.manifold());
  }
  EXPECT_EQ(lazy.stats().created, 1u);
  // Apart again (still one broadphase pair): the points are dropped by the refresh, the empty
  // manifold stays for `keep` steps and is released at the next.
  for (int s = 0; s < keep; ++s) {
    both(0.01f, 0, 0);
    ASSERT_EQ(lazy.pairs(), 1);
    EXPECT_EQ(lazy.manifolds(), 1) << s;
    EXPECT_EQ(lazy.manifold()->getNumContacts(), 0) << s;
  }
  both(0.01f, 0, 0);
  EXPECT_EQ(lazy.manifolds(), 0);
  EXPECT_EQ(lazy.stats().released, 1u);
  EXPECT_EQ(bullet.manifolds(), 1);
  // Touching again: a new manifold with Bullet's points (Bullet's empty one refills).
  both(-0.001f, 0.03f, 0.004f);
  ASSERT_EQ(lazy.manifolds(), 1);
  EXPECT_EQ(lazy.stats().created, 2u);
  ExpectSamePoints(lazy.manifold(), bullet.manifold());
  // Out of the broadphase: the pair and its algorithm go, and the manifold with it.
  both(1.0f, 0, 0);
  EXPECT_EQ(lazy.pairs(), 0);
  EXPECT_EQ(lazy.manifolds(), 0);
}

// keep_steps 0: released at the first empty step; negative counts as 0.
TEST(LazyManifoldsTest, KeepZeroReleasesAtTheFirstEmptyStep) {
  for (int keep : {0, -5}) {
    Pair lazy(true, keep);
    lazy.Detect(btVector3(0, 0.148f, 0), 0);
    ASSERT_EQ(lazy.manifolds(), 1);
    lazy.Detect(btVector3(0, 0.16f, 0), 0);
    EXPECT_EQ(lazy.manifolds(), 0) << keep;
    EXPECT_EQ(lazy.stats().released, 1u);
  }
}

PhysicsConfig Weightless(bool lazy) {
  PhysicsConfig cfg;
  cfg.lazy_box_manifolds = lazy;
  cfg.lazy_manifold_keep_steps = 3;
  cfg.gravity = Vec3f{0, 0, 0};
  cfg.sleeping = false;
  return cfg;
}

int Manifolds(const PhysicsWorld& w) {
  return w.BulletWorldForTesting()->getDispatcher()->getNumManifolds();
}

// Through PhysicsWorld: two weightless boxes 6 mm apart have a broadphase pair but no
// manifold; pushed together they get one and report one enter; pulled apart they report one
// exit, and the manifold goes after the keep time.
TEST(LazyManifoldsTest, WorldEventsExactlyOnceAndManifoldReleased) {
  PhysicsWorld w(Weightless(true));
  ASSERT_TRUE(Add(w, DynamicBox(1, {0, 0, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  ASSERT_TRUE(Add(w, DynamicBox(2, {0.206f, 0, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  std::vector<PhysicsEvent> events;
  for (int i = 0; i < 5; ++i) w.Step();
  ASSERT_EQ(w.BulletWorldForTesting()->getPairCache()->getNumOverlappingPairs(), 1);
  EXPECT_EQ(Manifolds(w), 0);
  // Box 2 moves into box 1 at 0.12 m/s (2 mm a step); both then drift on together or apart.
  ASSERT_TRUE(w.SetVelocity(2, {-0.12f, 0, 0}, {0, 0, 0}).ok());
  int touched_at = -1;
  for (int i = 0; i < 30 && touched_at < 0; ++i) {
    w.Step();
    if (Manifolds(w) == 1) touched_at = i;
  }
  ASSERT_GE(touched_at, 0);
  w.DrainEvents(&events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, PhysicsEventType::kCollisionEnter);
  EXPECT_EQ(events[0].entity_a, 1u);
  EXPECT_EQ(events[0].entity_b, 2u);
  // Pull apart to 6 mm (a broadphase pair remains) and hold still.
  events.clear();
  const Vec3f p1 = Pos(w, 1);
  ASSERT_TRUE(w.SetVelocity(1, {0, 0, 0}, {0, 0, 0}).ok());
  ASSERT_TRUE(w.SetVelocity(2, {0, 0, 0}, {0, 0, 0}).ok());
  ASSERT_TRUE(w.SetTransform(2, {p1.x + 0.206f, p1.y, p1.z}, {0, 0, 0, 1}).ok());
  int released_after = -1;
  for (int i = 0; i < 20; ++i) {
    w.Step();
    if (released_after < 0 && Manifolds(w) == 0) released_after = i;
  }
  ASSERT_EQ(w.BulletWorldForTesting()->getPairCache()->getNumOverlappingPairs(), 1);
  EXPECT_EQ(Manifolds(w), 0);
  EXPECT_EQ(released_after, 3);  // empty at step 0, kept 3 more (lazy_manifold_keep_steps)
  w.DrainEvents(&events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, PhysicsEventType::kCollisionExit);
  // Touch again: a second enter, from a new manifold.
  events.clear();
  ASSERT_TRUE(w.SetVelocity(2, {-0.12f, 0, 0}, {0, 0, 0}).ok());
  for (int i = 0; i < 30 && Manifolds(w) == 0; ++i) w.Step();
  w.DrainEvents(&events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, PhysicsEventType::kCollisionEnter);
}

// One box falling onto the ground is one pair, one manifold in either case: the setting changes
// nothing, bit for bit.
TEST(LazyManifoldsTest, SinglePairIsBitIdentical) {
  auto run = [](bool lazy) -> std::vector<Vec3f> {
    PhysicsConfig cfg;
    cfg.lazy_box_manifolds = lazy;
    PhysicsWorld w(cfg);
    EXPECT_TRUE(Add(w, Ground(1)).ok());
    EntitySpec box = DynamicBox(2, {0, 0.5f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
    EXPECT_TRUE(Add(w, box).ok());
    EXPECT_TRUE(w.SetVelocity(2, {0.5f, 0, 0}, {0, 0, 2.0f}).ok());
    std::vector<Vec3f> track;
    for (int i = 0; i < 120; ++i) {
      w.Step();
      track.push_back(Pos(w, 2));
    }
    return track;
  };
  const std::vector<Vec3f> off = run(false);
  const std::vector<Vec3f> on = run(true);
  ASSERT_EQ(off.size(), on.size());
  EXPECT_LT(off.back().y, 0.2f);  // it landed
  for (size_t i = 0; i < off.size(); ++i) {
    EXPECT_EQ(on[i].x, off[i].x) << i;
    EXPECT_EQ(on[i].y, off[i].y) << i;
    EXPECT_EQ(on[i].z, off[i].z) << i;
  }
}

// The stirred pile: the setting on keeps every box in the container, and fewer manifolds
// exist than broadphase pairs.
TEST(LazyManifoldsTest, StirredPileKeepsEveryBoxInside) {
  MultiObjectParams p;
  p.num_objects = 300;
  p.layers = 1;
  p.stirrer_reach = 0.75f;
  p.stirrer_angular_speed = 1.0f;
  p.config.lazy_box_manifolds = true;
  PhysSMultiObjectScene scene(p);
  for (int i = 0; i < 600; ++i) scene.Step();
  btDiscreteDynamicsWorld* bw = scene.world().BulletWorldForTesting();
  const int pairs = bw->getPairCache()->getNumOverlappingPairs();
  const int manifolds = bw->getDispatcher()->getNumManifolds();
  std::printf("[lazy] stirred 300-box pile: %d broadphase pairs, %d manifolds\n", pairs,
              manifolds);
  EXPECT_GT(manifolds, 0);
  EXPECT_LT(manifolds, pairs);
  const float lim = MultiObjectHalfWidth(p) + 0.05f;
  for (int i = 0; i < p.num_objects; ++i) {
    const Vec3f x = Pos(scene.world(), kSceneFirstBoxId + static_cast<uint32_t>(i));
    EXPECT_TRUE(std::abs(x.x) < lim && std::abs(x.z) < lim && x.y > -0.05f) << i;
  }
}

// With manifold reuse on, the setting is ignored (not combined): reuse's counters run.
TEST(LazyManifoldsTest, ReuseWinsOverLazy) {
  PhysicsConfig cfg = Weightless(true);
  cfg.manifold_reuse_distance = 0.001f;
  PhysicsWorld w(cfg);
  ASSERT_TRUE(Add(w, DynamicBox(1, {0, 0, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  ASSERT_TRUE(Add(w, DynamicBox(2, {0.206f, 0, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  for (int i = 0; i < 3; ++i) w.Step();
  EXPECT_GT(w.counters().narrowphase_full, 0u);
  EXPECT_EQ(Manifolds(w), 1);  // reuse keeps Bullet's manifold per pair
}

}  // namespace
}  // namespace edgephys::physics
