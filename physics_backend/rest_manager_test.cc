// Resting regions (PhysicsConfig::rest_freeze, physics/rest_manager.h): frozen bodies must cost
// less and behave as if they had never been frozen, within stated bounds. Speed itself is
// measured in bench/physics_cost_report.cc.
#include <gtest/gtest.h>

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "physics_backend/testing/physics_test_util.h"
#include "loadgen/scenes/scenes.h"
#include "physics_backend/state_hash.h"

namespace edgephys::physics {
namespace {

using namespace testing;  // physics_test_util.h: Add, ConfigWith, Dist, Ground, Pos

constexpr float kG = 9.81f;

PhysicsConfig Config(bool freeze) { return ConfigWith(&PhysicsConfig::rest_freeze, freeze); }

// A tight pile: a 4 x 4 layer of 0.2 m boxes touching each other, a 3 x 3 layer on top.
std::vector<uint32_t> AddPile(PhysicsWorld& world, float x0) {
  std::vector<uint32_t> ids;
  const float h = 0.1f;
  uint32_t id = 100;
  for (int i = 0; i < 4; ++i) {
    for (int k = 0; k < 4; ++k) {
      EXPECT_TRUE(Add(world, DynamicBox(id, {x0 + 2 * h * i, h, 2 * h * k}, {h, h, h}, 1.0f)).ok());
      ids.push_back(id++);
    }
  }
  for (int i = 0; i < 3; ++i) {
    for (int k = 0; k < 3; ++k) {
      EXPECT_TRUE(Add(world, DynamicBox(id, {x0 + h + 2 * h * i, 3 * h, h + 2 * h * k}, {h, h, h},
                                        1.0f))
                      .ok());
      ids.push_back(id++);
    }
  }
  return ids;
}

double Energy(const PhysicsWorld& world, const std::vector<uint32_t>& ids) {
  double e = 0;
  for (uint32_t id : ids) {
    const btRigidBody* b = world.RigidBodyForTesting(id);
    const double m = 1.0;  // every box in these tests has 1 kg
    const btVector3 v = b->getLinearVelocity();
    const btVector3 w = b->getAngularVelocity();
    const btVector3 inv = b->getInvInertiaDiagLocal();
    double rot = 0;
    // Box inertia is isotropic for cubes: I = 1 / inv (when not frozen; frozen bodies have w = 0).
    if (inv.x() > 0) rot = 0.5 * w.length2() / inv.x();
    e += 0.5 * m * v.length2() + rot + m * kG * b->getWorldTransform().getOrigin().y();
  }
  return e;
}

TEST(RestManagerTest, StirredPileFreezesItsRestingPartAndStepsFewerBodies) {
  // The quarter-plus scene at 300 boxes: one island (Bullet never sleeps any of it), most boxes
  // resting between paddle passes.
  auto run = [](bool freeze, size_t* frozen, size_t* simulated, size_t* escaped) {
    MultiObjectParams p;
    p.num_objects = 300;
    p.layers = 1;
    p.stirrer_reach = 0.75f;
    p.stirrer_angular_speed = 1.0f;
    p.config = Config(freeze);
    PhysSMultiObjectScene scene(p);
    size_t sim_sum = 0, frozen_sum = 0;
    for (int i = 0; i < 900; ++i) {
      scene.Step();
      if (i >= 600) {
        const PhysicsCounters c = scene.world().counters();
        sim_sum += c.dynamic_bodies - c.sleeping_bodies;
        frozen_sum += c.frozen_bodies;
      }
    }
    *frozen = frozen_sum / 300;
    *simulated = sim_sum / 300;
    const float lim = MultiObjectHalfWidth(p) + 0.05f;
    *escaped = 0;
    for (int i = 0; i < p.num_objects; ++i) {
      const Vec3f x = Pos(scene.world(), kSceneFirstBoxId + static_cast<uint32_t>(i));
      if (std::abs(x.x) > lim || std::abs(x.z) > lim || x.y < -0.05f) ++*escaped;
    }
  };
  size_t frozen_on = 0, sim_on = 0, esc_on = 0, frozen_off = 0, sim_off = 0, esc_off = 0;
  run(true, &frozen_on, &sim_on, &esc_on);
  run(false, &frozen_off, &sim_off, &esc_off);
  EXPECT_EQ(frozen_off, 0u);
  EXPECT_GT(sim_off, 280u) << "without freezing the stirred pile is one island that never sleeps";
  EXPECT_GT(frozen_on, 60u);
  EXPECT_LT(sim_on, sim_off * 8 / 10) << "frozen " << frozen_on;
  EXPECT_EQ(esc_on, 0u);
  EXPECT_EQ(esc_off, 0u);
}

TEST(RestManagerTest, FrozenPileReportsNothingAndHashesDeterministically) {
  auto build = [](PhysicsWorld& w) {
    EXPECT_TRUE(Add(w, Ground(1)).ok());
    return AddPile(w, 0);
  };
  PhysicsWorld a(Config(true)), b(Config(true));
  const std::vector<uint32_t> ids = build(a);
  build(b);
  std::vector<EntityState> moved;
  for (int i = 0; i < 90; ++i) {
    a.Step();
    b.Step();
    a.CollectStates(&moved);
  }
  EXPECT_EQ(a.counters().frozen_bodies, ids.size());
  for (int i = 0; i < 60; ++i) {
    a.Step();
    b.Step();
    a.CollectStates(&moved);
    EXPECT_TRUE(moved.empty()) << "a frozen body was reported at step " << i;
  }
  EXPECT_EQ(HashWorldState(a), HashWorldState(b));
  // Frozen bodies read as resting: zero velocity, where they were.
  Vec3f lin, ang;
  ASSERT_TRUE(a.GetVelocity(ids[0], &lin, &ang).ok());
  EXPECT_EQ(lin.x, 0.0f);
  EXPECT_EQ(lin.y, 0.0f);
  EXPECT_EQ(ang.z, 0.0f);
}

TEST(RestManagerTest, BoxDroppedOnFrozenPileWakesItAndMatchesTheRunWithoutFreezing) {
  struct Result {
    std::vector<Vec3f> pos;
    size_t frozen_before = 0;
    uint64_t wakes = 0;
    double e0 = 0, e_max = 0;
  };
  auto run = [](bool freeze) {
    PhysicsWorld w(Config(freeze));
    EXPECT_TRUE(Add(w, Ground(1)).ok());
    std::vector<uint32_t> ids = AddPile(w, 0);
    for (int i = 0; i < 60; ++i) w.Step();  // settled (and frozen after 0.5 s)
    Result r;
    r.frozen_before = w.counters().frozen_bodies;
    // Dropped 0.6 m above the top layer, off-centre so it tips the boxes it lands on.
    EXPECT_TRUE(Add(w, DynamicBox(50, {0.27f, 1.0f, 0.21f}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
    ids.push_back(50);
    r.e0 = Energy(w, ids);
    r.e_max = r.e0;
    for (int i = 0; i < 180; ++i) {
      w.Step();
      r.e_max = std::max(r.e_max, Energy(w, ids));
    }
    r.wakes = w.counters().rest_wakes;
    for (uint32_t id : ids) r.pos.push_back(Pos(w, id));
    return r;
  };
  const Result on = run(true);
  const Result off = run(false);
  EXPECT_EQ(on.frozen_before, 25u);
  EXPECT_EQ(off.frozen_before, 0u);
  EXPECT_GE(on.wakes, 2u) << "the boxes under the impact must wake";
  float worst = 0;
  for (size_t i = 0; i < on.pos.size(); ++i) worst = std::max(worst, Dist(on.pos[i], off.pos[i]));
  EXPECT_LT(worst, 0.02f) << "the pile responds as without freezing";
  std::printf("[rest] drop on a frozen pile: worst box %.2f mm from the never-frozen run, "
              "%llu wakes\n", 1000.0 * worst, static_cast<unsigned long long>(on.wakes));
  // The dropped box came to rest on the pile in both runs.
  EXPECT_NEAR(on.pos.back().y, off.pos.back().y, 0.02f);
  // Energy never grows (beyond solver noise: 1 % of the drop's potential energy).
  EXPECT_LE(on.e_max, on.e0 + 0.01 * kG * 0.6);
}

TEST(RestManagerTest, RemovingTheSupportMakesAFrozenStackFallFreely) {
  PhysicsWorld w(Config(true));
  // A static shelf at y = 1 (top face), two boxes stacked on it.
  ASSERT_TRUE(Add(w, StaticBox(2, {0, 0.95f, 0}, {0.5f, 0.05f, 0.5f})).ok());
  ASSERT_TRUE(Add(w, DynamicBox(10, {0, 1.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  ASSERT_TRUE(Add(w, DynamicBox(11, {0, 1.3f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  for (int i = 0; i < 60; ++i) w.Step();
  ASSERT_EQ(w.counters().frozen_bodies, 2u);
  const float y10 = Pos(w, 10).y, y11 = Pos(w, 11).y;
  ASSERT_TRUE(w.RemoveEntity(2).ok());
  EXPECT_EQ(w.counters().frozen_bodies, 1u) << "the box on the shelf wakes at once";
  const double dt = w.config().fixed_dt;
  for (int n = 1; n <= 30; ++n) {
    w.Step();
    // Semi-implicit Euler free fall from rest: y0 - g dt^2 n (n + 1) / 2.
    EXPECT_NEAR(Pos(w, 10).y, y10 - kG * dt * dt * n * (n + 1) / 2.0, 1e-4) << "step " << n;
    // The top box wakes one step later (its support moved): the same fall, one step behind.
    const int m = n - 1;
    EXPECT_NEAR(Pos(w, 11).y, y11 - kG * dt * dt * m * (m + 1) / 2.0, 1e-4) << "step " << n;
  }
  EXPECT_EQ(w.counters().frozen_bodies, 0u);
}

TEST(RestManagerTest, PaddleSweepingIntoFrozenBoxesPushesThemAndNoneTunnelsOrEscapes) {
  PhysicsWorld w(Config(true));
  const float half = 1.2f;
  ASSERT_TRUE(Add(w, Ground(1)).ok());
  ASSERT_TRUE(Add(w, StaticBox(2, {half + 0.1f, 0.5f, 0}, {0.1f, 0.5f, half + 0.2f})).ok());
  ASSERT_TRUE(Add(w, StaticBox(3, {-half - 0.1f, 0.5f, 0}, {0.1f, 0.5f, half + 0.2f})).ok());
  ASSERT_TRUE(Add(w, StaticBox(4, {0, 0.5f, half + 0.1f}, {half, 0.5f, 0.1f})).ok());
  ASSERT_TRUE(Add(w, StaticBox(5, {0, 0.5f, -half - 0.1f}, {half, 0.5f, 0.1f})).ok());
  std::vector<uint32_t> ids;
  std::vector<Vec3f> start;
  for (int i = 0; i < 8; ++i) {
    for (int k = 0; k < 8; ++k) {
      const Vec3f p{-1.05f + 0.3f * i, 0.1f, -1.05f + 0.3f * k};
      const uint32_t id = 100 + static_cast<uint32_t>(8 * i + k);
      ASSERT_TRUE(Add(w, DynamicBox(id, p, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
      ids.push_back(id);
    }
  }
  // The paddle: kinematic, 0.8 m half length, 0.05 m half thickness, parked along +X at first.
  EntitySpec paddle = StaticBox(6, {0, 0.2f, 0}, {0.8f, 0.2f, 0.05f});
  paddle.flags = static_cast<uint32_t>(schema::EntityFlags::Kinematic);
  paddle.rigid_body = RigidBodySpec{};
  paddle.rigid_body->mass = 0;
  paddle.rigid_body->kinematic = true;
  ASSERT_TRUE(Add(w, paddle).ok());
  for (int i = 0; i < 60; ++i) w.Step();
  for (uint32_t id : ids) start.push_back(Pos(w, id));
  ASSERT_GT(w.counters().frozen_bodies, 40u);
  const double omega = 3.0;  // rad/s: the tip moves 4 cm per step
  const double dt = w.config().fixed_dt;
  float deepest = 0;
  for (int n = 1; n <= 240; ++n) {
    const float a = static_cast<float>(omega * dt * n);
    const Quatf q = testing::AxisAngle(0, 1, 0, a);
    ASSERT_TRUE(w.MoveToTransform(6, {0, 0.2f, 0}, q).ok());
    w.Step();
    // No box centre inside the paddle (its slab grown by 5 cm of the box): nothing tunnels.
    const btTransform pose(btQuaternion(btVector3(0, 1, 0), a), btVector3(0, 0.2f, 0));
    for (uint32_t id : ids) {
      const Vec3f p = Pos(w, id);
      const btVector3 local = pose.invXform(btVector3(p.x, p.y, p.z));
      if (std::abs(local.x()) < 0.8f && std::abs(local.z()) < 0.05f + 0.05f) {
        deepest = std::max(deepest, 0.1f - std::abs(local.z()));
      }
    }
  }
  EXPECT_EQ(deepest, 0.0f) << "a box centre came within 5 cm of the paddle's mid-plane";
  size_t pushed = 0, escaped = 0;
  for (size_t i = 0; i < ids.size(); ++i) {
    const Vec3f p = Pos(w, ids[i]);
    if (Dist(p, start[i]) > 0.05f) ++pushed;
    if (std::abs(p.x) > half + 0.02f || std::abs(p.z) > half + 0.02f || p.y < 0.05f) ++escaped;
  }
  EXPECT_GT(pushed, 20u) << "the paddle must push the frozen boxes in its path";
  EXPECT_EQ(escaped, 0u);
  EXPECT_GT(w.counters().rest_wakes, 20u);
}

TEST(RestManagerTest, ApiCallsUnfreezeAndJointsOrSoftBodiesPreventFreezing) {
  PhysicsWorld w(Config(true));
  ASSERT_TRUE(Add(w, Ground(1)).ok());
  ASSERT_TRUE(Add(w, DynamicBox(10, {0, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  // A box hinged to the world never freezes.
  EntitySpec hinged = DynamicBox(11, {2, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  JointSpec j;
  j.kind = schema::JointKind::Hinge;
  hinged.joints.push_back(j);
  ASSERT_TRUE(Add(w, hinged).ok());
  // A box under a soft body never freezes.
  ASSERT_TRUE(Add(w, DynamicBox(12, {-2, 0.1f, 0}, {0.3f, 0.1f, 0.3f}, 1.0f)).ok());
  SoftBodySpec cube = MakeLatticeCubeSoftBody(200.0f);
  for (size_t i = 0; i < cube.particles.size(); i += 3) cube.particles[i] += -2.1f;
  EntitySpec soft;
  soft.id = 13;
  soft.soft_body = cube;
  ASSERT_TRUE(Add(w, soft).ok());
  for (int i = 0; i < 120; ++i) w.Step();
  EXPECT_TRUE(w.RigidBodyForTesting(10)->isStaticObject()) << "box 10 should be frozen";
  EXPECT_FALSE(w.RigidBodyForTesting(11)->isStaticObject());
  EXPECT_FALSE(w.RigidBodyForTesting(12)->isStaticObject());
  // SetVelocity on a frozen body moves it as if it had never been frozen.
  ASSERT_TRUE(w.SetVelocity(10, {1, 0, 0}, {}).ok());
  EXPECT_FALSE(w.RigidBodyForTesting(10)->isStaticObject());
  EXPECT_EQ(w.RigidBodyForTesting(10)->getInvMass(), 1.0f);
  const float x0 = Pos(w, 10).x;
  w.Step();
  EXPECT_GT(Pos(w, 10).x, x0 + 0.01f);
}

// Few frozen bodies among many pairs (the full stir): BeforeStep asks the broadphase around each
// frozen body instead of walking the pairs, and a box thrown at a frozen one still wakes it.
TEST(RestManagerTest, FewFrozenAmongManyPairsStillWakeWhenSomethingArrives) {
  PhysicsWorld world(Config(true));
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  ASSERT_TRUE(Add(world, DynamicBox(2, {0, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  // 40 boxes kept moving far away: 40 pairs with the ground, none of them may freeze.
  for (uint32_t i = 0; i < 40; ++i) {
    ASSERT_TRUE(Add(world, DynamicBox(100 + i, {10.0f + 0.5f * i, 0.1f, 0}, {0.1f, 0.1f, 0.1f},
                                      1.0f)).ok());
  }
  auto keep_moving = [&]() {
    for (uint32_t i = 0; i < 40; ++i) (void)world.SetVelocity(100 + i, {0, 0, 0.3f}, {0, 0, 0});
  };
  for (int i = 0; i < 60; ++i) {
    keep_moving();
    world.Step();
  }
  ASSERT_EQ(world.counters().frozen_bodies, 1u);  // only box 2 rests
  const uint64_t wakes = world.counters().rest_wakes;
  EntitySpec thrown = DynamicBox(3, {-0.6f, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  thrown.rigid_body->linear_velocity = Vec3f{3.0f, 0, 0};
  ASSERT_TRUE(Add(world, thrown).ok());
  EXPECT_EQ(world.counters().frozen_bodies, 1u);  // 0.4 m away: not woken by the add
  float gap_at_wake = -1;  // C's leading face to A's near face when A woke (m)
  for (int i = 0; i < 30; ++i) {
    keep_moving();
    world.Step();
    if (gap_at_wake < 0 && world.counters().rest_wakes > wakes) {
      gap_at_wake = (Pos(world, 2).x - 0.1f) - (Pos(world, 3).x + 0.1f);
    }
  }
  EXPECT_GT(world.counters().rest_wakes, wakes);
  // Woken by the overlap rule before the contact (the impulse rule alone would wake it only
  // after the hit, with no gap left).
  EXPECT_GT(gap_at_wake, 0.0f);
  EXPECT_GT(Pos(world, 2).x, 0.05f);            // it was pushed
  EXPECT_LT(Pos(world, 3).x, Pos(world, 2).x);  // nothing passed through it
}

}  // namespace
}  // namespace edgephys::physics
