// Containment (physics/containment.h): dynamic bodies stay out of static boxes without CCD
// sweeps, and bodies the rule does not concern are left exactly as Bullet moves them. The
// full-stir figures (escapes, step time) come from bench/physics_cost_report.cc; no timing
// here.
#include <gtest/gtest.h>

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <vector>

#include "physics_backend/physics_test_util.h"

namespace edgephys::physics {
namespace {

using testing::Add;
using testing::AxisAngle;
using testing::Ground;
using testing::Pos;
using testing::Vel;

// The configs compared: containment without sweeps, and neither (what containment replaces).
PhysicsConfig Contained() {
  PhysicsConfig c;
  c.ccd = false;
  c.containment = true;
  return c;
}
PhysicsConfig Unprotected() {
  PhysicsConfig c;
  c.ccd = false;
  c.containment = false;
  return c;
}

// A closed room: inner half width 1 m on every axis, walls 1 cm thick (ids 1-6), restitution 1.
constexpr float kInner = 1.0f;
constexpr float kWallHalf = 0.005f;
void AddClosedRoom(PhysicsWorld& w) {
  const float c = kInner + kWallHalf, span = kInner + 2 * kWallHalf;
  const Vec3f centres[6] = {{c, 0, 0}, {-c, 0, 0}, {0, c, 0}, {0, -c, 0}, {0, 0, c}, {0, 0, -c}};
  const Vec3f halves[6] = {{kWallHalf, span, span}, {kWallHalf, span, span},
                           {span, kWallHalf, span}, {span, kWallHalf, span},
                           {span, span, kWallHalf}, {span, span, kWallHalf}};
  for (uint32_t i = 0; i < 6; ++i) {
    EntitySpec wall = StaticBox(1 + i, centres[i], halves[i]);
    wall.rigid_body = RigidBodySpec{};
    wall.rigid_body->mass = 0;
    wall.rigid_body->restitution = 1.0f;
    ASSERT_TRUE(Add(w, wall).ok());
  }
}

// A 5 cm sphere (or a 5 cm box) from the room's centre at 50 m/s along `dir`, no gravity,
// restitution 0.5; the largest |coordinate| its centre reaches in 60 steps.
struct Shot {
  float max_abs = 0;      // largest |x|, |y| or |z| of the centre (m)
  float speed_back = 0;   // speed along -dir after the first contact (m/s)
  uint64_t contained = 0;
};
Shot Fire(const PhysicsConfig& cfg, const Vec3f& dir, bool box) {
  PhysicsWorld w(cfg);
  AddClosedRoom(w);
  EntitySpec b = box ? DynamicBox(10, {0, 0, 0}, {0.05f, 0.05f, 0.05f}, 0.1f)
                     : DynamicSphere(10, {0, 0, 0}, 0.05f, 0.1f);
  b.rigid_body->use_gravity = false;
  b.rigid_body->restitution = 0.5f;
  const float len = std::sqrt(dir.x * dir.x + dir.y * dir.y + dir.z * dir.z);
  const Vec3f u{dir.x / len, dir.y / len, dir.z / len};
  b.rigid_body->linear_velocity = Vec3f{50 * u.x, 50 * u.y, 50 * u.z};
  EXPECT_TRUE(Add(w, b).ok());
  Shot s;
  bool back = false;
  for (int i = 0; i < 60; ++i) {
    w.Step();
    const Vec3f p = Pos(w, 10);
    s.max_abs = std::max({s.max_abs, std::abs(p.x), std::abs(p.y), std::abs(p.z)});
    const Vec3f v = Vel(w, 10);
    const float along = v.x * u.x + v.y * u.y + v.z * u.z;
    if (!back && along < 0) back = true, s.speed_back = -along;
  }
  s.contained = w.counters().contained;
  return s;
}

TEST(ContainmentTest, FastSmallBodyFiredAtEachWallStaysInside) {
  const Vec3f dirs[] = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0}, {0, 0, 1}, {0, 0, -1},
                        {1, 1, 0.3f}};  // the last one into an edge
  for (const bool box : {false, true}) {
    for (const Vec3f& d : dirs) {
      const Shot s = Fire(Contained(), d, box);
      SCOPED_TRACE(::testing::Message() << (box ? "box" : "sphere") << " towards (" << d.x << ", "
                                      << d.y << ", " << d.z << ")");
      // 0.83 m per step; the centre never passes a wall's inner face (it may touch: the
      // box's corner reaches 8.7 cm from its centre).
      EXPECT_LT(s.max_abs, kInner) << s.max_abs;
      EXPECT_GT(s.contained, 0u);
      // It bounces back (restitution 0.5 x the wall's 1 on the first contact: 25 m/s for a
      // head-on sphere) instead of stopping dead in the wall.
      EXPECT_GT(s.speed_back, 5.0f);
    }
  }
  // What the rule replaces: without it (and without CCD) the sphere leaves the room.
  EXPECT_GT(Fire(Unprotected(), {1, 0, 0}, false).max_abs, kInner + 2 * kWallHalf);
}

TEST(ContainmentTest, HeadOnBounceKeepsTheRestitution) {
  // A sphere that was clear of the wall is put back touching it with its normal velocity
  // reflected by e = 0.5 x 1 (Bullet's product): 50 m/s in, 25 m/s out.
  const Shot s = Fire(Contained(), {1, 0, 0}, false);
  EXPECT_NEAR(s.speed_back, 25.0f, 0.5f);
}

TEST(ContainmentTest, RotatedWallKeepsItsSide) {
  // A wall turned 30 degrees about Y, 1 cm thick; a sphere fired at it along +x at 50 m/s ends
  // on the side it came from (signed distance along the wall's normal stays negative).
  PhysicsWorld w(Contained());
  const Quatf q = AxisAngle(0, 1, 0, 0.5235988f);
  ASSERT_TRUE(Add(w, StaticBox(1, {1.0f, 0, 0}, {kWallHalf, 1.0f, 1.0f}, q)).ok());
  EntitySpec ball = DynamicSphere(2, {0, 0, 0}, 0.05f, 0.1f);
  ball.rigid_body->use_gravity = false;
  ball.rigid_body->linear_velocity = Vec3f{50.0f, 0, 0};
  ASSERT_TRUE(Add(w, ball).ok());
  const btVector3 n = btMatrix3x3(btQuaternion(q.x, q.y, q.z, q.w)).getColumn(0);
  float worst = -1;
  for (int i = 0; i < 30; ++i) {
    w.Step();
    const Vec3f p = Pos(w, 2);
    worst = std::max(worst, static_cast<float>(n.dot(btVector3(p.x - 1.0f, p.y, p.z))));
  }
  EXPECT_LT(worst, -kWallHalf);  // the centre never reaches the wall's near face
  EXPECT_GT(w.counters().contained, 0u);
}

// A row of boxes on the floor of a channel, shoved against a 1 cm end wall by a kinematic
// piston that keeps going until it is 0.25 m from the wall: the box at the wall is squeezed.
// Returns the largest x its centre reaches (the wall's near face is at x = 1).
float SqueezeMaxX(const PhysicsConfig& cfg, uint64_t* contained) {
  PhysicsWorld w(cfg);
  EXPECT_TRUE(Add(w, Ground(1)).ok());
  EXPECT_TRUE(Add(w, StaticBox(2, {1.0f + kWallHalf, 0.5f, 0}, {kWallHalf, 0.5f, 1.0f})).ok());
  // Channel sides and a lid: the boxes cannot get out of the way upwards or sideways.
  EXPECT_TRUE(Add(w, StaticBox(3, {0, 0.1f, 0.16f}, {2.0f, 0.1f, 0.05f})).ok());
  EXPECT_TRUE(Add(w, StaticBox(4, {0, 0.1f, -0.16f}, {2.0f, 0.1f, 0.05f})).ok());
  EXPECT_TRUE(Add(w, StaticBox(5, {0, 0.26f, 0}, {2.0f, 0.05f, 0.2f})).ok());
  EntitySpec piston = StaticBox(6, {-0.4f, 0.1f, 0}, {0.05f, 0.09f, 0.1f});
  piston.rigid_body = RigidBodySpec{};
  piston.rigid_body->mass = 0;
  piston.rigid_body->kinematic = true;
  EXPECT_TRUE(Add(w, piston).ok());
  for (uint32_t i = 0; i < 5; ++i) {
    EXPECT_TRUE(
        Add(w, DynamicBox(10 + i, {0.9f - 0.21f * i, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  }
  float max_x = 0, x = -0.4f;
  for (int i = 0; i < 240; ++i) {
    x = std::min(x + 1.0f / 60.0f, 1.0f - 0.25f - 0.05f);
    EXPECT_TRUE(w.MoveToTransform(6, {x, 0.1f, 0}, Quatf{0, 0, 0, 1}).ok());
    w.Step();
    max_x = std::max(max_x, Pos(w, 10).x);
  }
  if (contained != nullptr) *contained = w.counters().contained;
  return max_x;
}

TEST(ContainmentTest, BoxSqueezedAgainstAWallByAPileStaysInside) {
  uint64_t contained = 0;
  const float with = SqueezeMaxX(Contained(), &contained);
  const float without = SqueezeMaxX(Unprotected(), nullptr);
  std::printf("[squeeze] box centre max x: contained %.3f m (%llu moves), unprotected %.3f m "
              "(wall face 1.0)\n",
              with, static_cast<unsigned long long>(contained), without);
  // Its support may reach half its extent into the wall (5 cm), never its centre.
  EXPECT_LT(with, 1.0f - 0.05f + 0.01f);
  EXPECT_GT(contained, 0u);
  EXPECT_GT(without, 1.0f);  // the squeeze this test builds does push it through unprotected
  // With split impulse the solver already moves bodies before the integration; the rule
  // compares with the centre at the start of the step, so it holds there too.
  PhysicsConfig split = Contained();
  split.split_impulse = true;
  EXPECT_LT(SqueezeMaxX(split, nullptr), 1.0f - 0.05f + 0.01f);
}

// Poses and velocities of a set of bodies, bitwise (what "untouched" means).
std::vector<float> Snapshot(const PhysicsWorld& w, const std::vector<uint32_t>& ids) {
  std::vector<float> out;
  for (uint32_t id : ids) {
    EntityState s;
    Vec3f lin, ang;
    EXPECT_TRUE(w.GetState(id, &s).ok());
    EXPECT_TRUE(w.GetVelocity(id, &lin, &ang).ok());
    out.insert(out.end(), {s.position.x, s.position.y, s.position.z, s.rotation.x, s.rotation.y,
                           s.rotation.z, s.rotation.w, lin.x, lin.y, lin.z, ang.x, ang.y, ang.z});
  }
  return out;
}

// An open-topped room (floor and four 1 m walls, 0.2 m thick, inner half width 1 m) and bodies
// that the rule does not concern: one spawned outside that slides along the outside of a wall,
// one that flies out over a wall's top, one that lands and rests on the floor, a box that slides
// into a wall and stops against it. Stepped 240 times; returns the bodies' final state.
std::vector<float> OutsideAndOverTheTop(const PhysicsConfig& cfg, uint64_t* contained) {
  PhysicsWorld w(cfg);
  EXPECT_TRUE(Add(w, Ground(1, 0.5f, 0.0f, 5.0f)).ok());
  EXPECT_TRUE(Add(w, StaticBox(2, {1.1f, 0.5f, 0}, {0.1f, 0.5f, 1.2f})).ok());
  EXPECT_TRUE(Add(w, StaticBox(3, {-1.1f, 0.5f, 0}, {0.1f, 0.5f, 1.2f})).ok());
  EXPECT_TRUE(Add(w, StaticBox(4, {0, 0.5f, 1.1f}, {1.0f, 0.5f, 0.1f})).ok());
  EXPECT_TRUE(Add(w, StaticBox(5, {0, 0.5f, -1.1f}, {1.0f, 0.5f, 0.1f})).ok());
  EntitySpec outside = DynamicBox(10, {1.5f, 0.1f, -1.0f}, {0.1f, 0.1f, 0.1f}, 1.0f);
  outside.rigid_body->linear_velocity = Vec3f{0, 0, 3.0f};  // along the +x wall's outside
  EntitySpec over = DynamicSphere(11, {0.5f, 1.2f, 0}, 0.05f, 0.1f);
  over.rigid_body->use_gravity = false;
  over.rigid_body->linear_velocity = Vec3f{6.0f, 0, 0};  // out over the +x wall's top
  // Slow enough to reach at most 3.3 cm (< half its extent) into what it hits in one step.
  EntitySpec rest = DynamicBox(12, {-0.5f, 0.3f, 0.3f}, {0.1f, 0.1f, 0.1f}, 1.0f);
  EntitySpec slide = DynamicBox(13, {0, 0.1f, 0.5f}, {0.1f, 0.1f, 0.1f}, 1.0f);
  slide.rigid_body->linear_velocity = Vec3f{0, 0, 2.5f};  // into the +z wall
  for (const EntitySpec& s : {outside, over, rest, slide}) EXPECT_TRUE(Add(w, s).ok());
  for (int i = 0; i < 240; ++i) w.Step();
  *contained = w.counters().contained;
  EXPECT_GT(Pos(w, 11).x, 1.2f);  // the sphere did leave over the top
  EXPECT_GT(Pos(w, 10).x, 1.2f);  // the outside box stayed outside
  return Snapshot(w, {10, 11, 12, 13});
}

TEST(ContainmentTest, BodiesItDoesNotConcernAreUntouched) {
  uint64_t contained = 1, unused = 0;
  const std::vector<float> with = OutsideAndOverTheTop(Contained(), &contained);
  const std::vector<float> without = OutsideAndOverTheTop(Unprotected(), &unused);
  EXPECT_EQ(contained, 0u);
  ASSERT_EQ(with.size(), without.size());
  EXPECT_EQ(std::memcmp(with.data(), without.data(), with.size() * sizeof(float)), 0)
      << "containment changed a body that never went deeper than half its extent into a wall";
}

TEST(ContainmentTest, BodySpawnedInsideAWallIsLeftToBullet) {
  // The centre starts inside the wall: not covered (the rule needs the side it came from).
  PhysicsWorld w(Contained());
  ASSERT_TRUE(Add(w, StaticBox(1, {0, 0, 0}, {0.5f, 0.5f, 0.5f})).ok());
  EntitySpec b = DynamicBox(2, {0.3f, 0, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  b.rigid_body->use_gravity = false;
  ASSERT_TRUE(Add(w, b).ok());
  w.Step();
  EXPECT_EQ(w.counters().contained, 0u);
}

TEST(ContainmentTest, RemovedWallNoLongerContains) {
  PhysicsWorld w(Contained());
  AddClosedRoom(w);
  ASSERT_TRUE(w.RemoveEntity(1).ok());  // the +x wall
  EntitySpec ball = DynamicSphere(10, {0, 0, 0}, 0.05f, 0.1f);
  ball.rigid_body->use_gravity = false;
  ball.rigid_body->linear_velocity = Vec3f{50.0f, 0, 0};
  ASSERT_TRUE(Add(w, ball).ok());
  for (int i = 0; i < 10; ++i) w.Step();
  EXPECT_GT(Pos(w, 10).x, 2.0f);
  EXPECT_EQ(w.counters().contained, 0u);
}

TEST(ContainmentTest, DroppedBoxesRestWhereTheyDoWithCcd) {
  // Boxes dropped from up to 1.4 m land at up to 5.2 m/s (8.7 cm per step, more than half a
  // box): the rule puts them back touching the ground where CCD's sweeps would stop them. They
  // come to rest where they do with CCD, and the two-box stack stands.
  PhysicsConfig ccd;  // the sweeps instead of the rule
  ccd.ccd = true;
  ccd.containment = false;
  const std::vector<Vec3f> with = testing::DropSceneRestingPositions(Contained());
  const std::vector<Vec3f> base = testing::DropSceneRestingPositions(ccd);
  ASSERT_EQ(with.size(), base.size());
  for (size_t i = 0; i < base.size(); ++i) {
    EXPECT_LT(testing::Dist(base[i], with[i]), 0.01f) << "body " << i;
  }
  EXPECT_NEAR(with[4].y, 0.1f, 0.01f);
  EXPECT_NEAR(with[5].y, 0.3f, 0.01f);
}

}  // namespace
}  // namespace edgephys::physics
