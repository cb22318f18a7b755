// The Bullet-level settings of PhysicsConfig (physics/bullet_world.h): each reaches Bullet, and
// each keeps the world correct where its header comment says it does. Speed is measured in
// bench/physics_cost_report.cc, not here.
#include <gtest/gtest.h>

#include <BulletCollision/CollisionDispatch/btSimulationIslandManager.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <vector>

#include "physics_backend/testing/physics_test_util.h"

namespace edgephys::physics {
namespace {

using testing::Add;
using testing::Ground;
using testing::Pos;

TEST(BulletWorldTest, SolverSettingsReachBullet) {
  {
    // The defaults: Bullet's solver modes, one solver batch (islands are still
    // built for sleeping), PhyS's solver with its response filter.
    PhysicsWorld world{PhysicsConfig{}};
    btDiscreteDynamicsWorld* w = world.BulletWorldForTesting();
    EXPECT_EQ(w->getSolverInfo().m_solverMode, SOLVER_USE_WARMSTARTING | SOLVER_SIMD);
    EXPECT_EQ(w->getSolverInfo().m_numIterations, 7);
    EXPECT_FALSE(w->getSimulationIslandManager()->getSplitIslands());
    EXPECT_EQ(w->getConstraintSolver()->getSolverType(), BT_SEQUENTIAL_IMPULSE_SOLVER);
  }
  {
    // The solver candidates reach Bullet.
    PhysicsConfig cfg;
    cfg.split_islands = false;
    cfg.two_friction_directions = true;
    cfg.friction_direction_caching = true;
    cfg.velocity_dependent_friction = false;
    PhysicsWorld world(cfg);
    btDiscreteDynamicsWorld* w = world.BulletWorldForTesting();
    EXPECT_EQ(w->getSolverInfo().m_solverMode,
              SOLVER_USE_WARMSTARTING | SOLVER_SIMD | SOLVER_USE_2_FRICTION_DIRECTIONS |
                  SOLVER_ENABLE_FRICTION_DIRECTION_CACHING |
                  SOLVER_DISABLE_VELOCITY_DEPENDENT_FRICTION_DIRECTION);
    EXPECT_FALSE(w->getSimulationIslandManager()->getSplitIslands());
  }
  PhysicsConfig cfg;
  cfg.solver = PhysicsConfig::Solver::kNNCG;
  cfg.interleave_friction = true;
  PhysicsWorld world(cfg);
  btDiscreteDynamicsWorld* w = world.BulletWorldForTesting();
  EXPECT_TRUE(w->getSolverInfo().m_solverMode & SOLVER_INTERLEAVE_CONTACT_AND_FRICTION_CONSTRAINTS);
  EXPECT_EQ(w->getConstraintSolver()->getSolverType(), BT_NNCG_SOLVER);
}

void ExpectSameDrop(const PhysicsConfig& cfg, const char* what) {
  PhysicsConfig bullet_pairs;  // Bullet's AABB margin, islands split, CCD against everything
  bullet_pairs.aabb_margin = kBulletAabbMargin;
  bullet_pairs.split_islands = true;
  const std::vector<Vec3f> base = testing::DropSceneRestingPositions(bullet_pairs);
  const std::vector<Vec3f> got = testing::DropSceneRestingPositions(cfg);
  for (size_t i = 0; i < base.size(); ++i) {
    EXPECT_LT(testing::Dist(base[i], got[i]), 0.01f) << what << ", body " << i;
  }
  EXPECT_NEAR(got[4].y, 0.1f, 0.01f) << what;  // the stack stands: 0.1 and 0.3
  EXPECT_NEAR(got[5].y, 0.3f, 0.01f) << what;
}

TEST(BulletWorldTest, PairFindingSettingsKeepEveryContact) {
  PhysicsConfig small_margin;
  small_margin.split_islands = true;
  small_margin.aabb_margin = 0.005f;
  ExpectSameDrop(small_margin, "aabb_margin 5 mm");
  PhysicsConfig hysteresis;
  hysteresis.aabb_margin = 0.005f;
  hysteresis.aabb_hysteresis = 0.02f;
  ExpectSameDrop(hysteresis, "aabb_hysteresis 2 cm");
  PhysicsConfig one_batch;
  one_batch.aabb_margin = kBulletAabbMargin;
  one_batch.split_islands = false;
  ExpectSameDrop(one_batch, "split_islands off");
  PhysicsConfig static_ccd;
  static_ccd.ccd_static_only = true;
  ExpectSameDrop(static_ccd, "ccd_static_only");
  ExpectSameDrop(PhysicsConfig{}, "the defaults");
}

TEST(BulletWorldTest, AabbHysteresisUpdatesTheBroadphaseOnlyWhenTheBodyLeavesIt) {
  PhysicsConfig cfg;
  cfg.aabb_margin = 0.005f;
  cfg.aabb_hysteresis = 0.02f;
  cfg.gravity = Vec3f{0, 0, 0};
  cfg.sleeping = false;
  PhysicsWorld world(cfg);
  EntitySpec box = DynamicBox(2, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  box.rigid_body->linear_velocity = Vec3f{0.3f, 0, 0};  // 5 mm per step
  ASSERT_TRUE(Add(world, box).ok());
  btRigidBody* body = world.RigidBodyForTesting(2);
  int updates = 0;
  btVector3 last_min = body->getBroadphaseHandle()->m_aabbMin;
  for (int i = 0; i < 60; ++i) {
    world.Step();
    const btBroadphaseProxy* p = body->getBroadphaseHandle();
    btVector3 mn, mx;
    body->getCollisionShape()->getAabb(body->getWorldTransform(), mn, mx);
    // The broadphase always holds the body (with at least the margin around it)...
    ASSERT_LE(p->m_aabbMin.x(), mn.x() - 0.005f + 1e-5f) << "step " << i;
    ASSERT_GE(p->m_aabbMax.x(), mx.x() + 0.005f - 1e-5f) << "step " << i;
    ASSERT_LE(p->m_aabbMax.x() - p->m_aabbMin.x(), 0.2f + 2 * 0.025f + 0.006f + 1e-4f);
    if (p->m_aabbMin != last_min) ++updates;
    last_min = p->m_aabbMin;
  }
  // ...but 30 cm of motion at 5 mm a step crosses the 2 cm hysteresis about 30 / 2 times, not
  // 60 (every step).
  EXPECT_GE(updates, 8);
  EXPECT_LE(updates, 20);
  EXPECT_NEAR(Pos(world, 2).x, 0.3f, 0.01f);
}

// A small fast body against a thin slab, 50 m/s (0.83 m a step against a 1 cm slab).
float FastSphereMaxX(bool static_only, bool dynamic_slab) {
  PhysicsConfig cfg;
  cfg.ccd_static_only = static_only;
  PhysicsWorld world(cfg);
  EntitySpec slab = dynamic_slab ? DynamicBox(1, {1.0f, 0, 0}, {0.005f, 1.0f, 1.0f}, 100.0f)
                                 : StaticBox(1, {1.0f, 0, 0}, {0.005f, 1.0f, 1.0f});
  if (dynamic_slab) slab.rigid_body->use_gravity = false;
  EXPECT_TRUE(Add(world, slab).ok());
  EntitySpec ball = DynamicSphere(2, {0, 0, 0}, 0.05f, 0.1f);
  ball.rigid_body->use_gravity = false;
  ball.rigid_body->linear_velocity = Vec3f{50.0f, 0, 0};
  EXPECT_TRUE(Add(world, ball).ok());
  const int mask_before = world.RigidBodyForTesting(2)->getBroadphaseHandle()->m_collisionFilterMask;
  float mx = 0;
  for (int i = 0; i < 30; ++i) {
    world.Step();
    mx = std::max(mx, Pos(world, 2).x);
  }
  // The narrowed mask is only ever seen by the sweeps.
  EXPECT_EQ(world.RigidBodyForTesting(2)->getBroadphaseHandle()->m_collisionFilterMask,
            mask_before);
  return mx;
}

TEST(BulletWorldTest, StaticOnlyCcdStopsAtWallsAndOnlyAtWalls) {
  // Static wall: stopped either way (the suite's CCD bound).
  EXPECT_LE(FastSphereMaxX(false, false) + 0.05f, 1.005f);
  EXPECT_LE(FastSphereMaxX(true, false) + 0.05f, 1.005f);
  // Thin dynamic slab: full CCD stops the sphere; static-only lets it pass (the documented
  // accuracy cost of the setting).
  EXPECT_LE(FastSphereMaxX(false, true) + 0.05f, 1.05f);
  EXPECT_GT(FastSphereMaxX(true, true), 2.0f);
}

}  // namespace
}  // namespace edgephys::physics
