// PhyS's contact solver (physics/contact_solver.h): the response filter of the one-batch solve,
// and patch friction against analytic results. Speed is measured in bench/physics_cost_report.cc
// (docs/benchmarks.md), not here.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "physics_backend/testing/physics_test_util.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {
namespace {

using namespace testing;  // physics_test_util.h: Add, ConfigWith, Ground, Pos, Vel

constexpr double kG = 9.81;

PhysicsConfig Patch(bool on) { return ConfigWith(&PhysicsConfig::patch_friction, on); }

// With one solver batch (split_islands = false) Bullet hands the solver every manifold, also
// those with a trigger; without the response filter the trigger stopped the sphere like a wall.
TEST(ContactSolverTest, OneBatchSolveLetsBodiesPassThroughTriggers) {
  for (const bool patch : {false, true}) {
    PhysicsConfig cfg = Patch(patch);
    cfg.split_islands = false;
    PhysicsWorld world(cfg);
    EntitySpec zone = StaticBox(1, {0, 5, 0}, {0.5f, 0.5f, 0.5f});
    zone.colliders[0].is_trigger = true;
    ASSERT_TRUE(Add(world, zone).ok());
    ASSERT_TRUE(Add(world, DynamicSphere(2, {0, 7, 0}, 0.1f, 1.0f)).ok());
    ASSERT_TRUE(Add(world, DynamicBox(3, {3, 7, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
    ASSERT_TRUE(Add(world, Ground(4)).ok());
    std::vector<PhysicsEvent> events;
    for (int i = 0; i < 120; ++i) world.Step();
    world.DrainEvents(&events);
    int enter = 0, exit = 0;
    for (const PhysicsEvent& ev : events) {
      if (ev.entity_a == 1 && ev.entity_b == 2) {
        enter += ev.type == PhysicsEventType::kTriggerEnter;
        exit += ev.type == PhysicsEventType::kTriggerExit;
      }
    }
    EXPECT_EQ(enter, 1) << "patch " << patch;
    EXPECT_EQ(exit, 1) << "patch " << patch;
    EXPECT_LT(Pos(world, 2).y, 4.0f) << "the trigger stopped the sphere (patch " << patch << ")";
    // Solid contacts still respond in the same batch: the box lands on the ground.
    EXPECT_NEAR(Pos(world, 3).y, 0.1f, 0.01f) << "patch " << patch;
  }
}

// A 0.2 m cube on flat ground under gravity tilted by `angle` towards the direction (cos(yaw), 0,
// sin(yaw)): a slope of that angle, sliding along an arbitrary direction of the tangent plane.
struct SlopeRun {
  double along = 0;         // displacement along the slope after `seconds` (m)
  double across = 0;        // displacement across it (m)
  double acceleration = 0;  // along the slope, from the velocities at 0.5 s and 1.5 s
};

SlopeRun Slope(bool patch, double angle, double yaw, float mu, double seconds) {
  PhysicsConfig cfg = Patch(patch);
  const double gt = kG * std::sin(angle);
  cfg.gravity = Vec3f{static_cast<float>(gt * std::cos(yaw)), static_cast<float>(-kG * std::cos(angle)),
                      static_cast<float>(gt * std::sin(yaw))};
  PhysicsWorld world(cfg);
  EXPECT_TRUE(Add(world, Ground(1, 1.0f)).ok());  // combined friction = 1.0 * mu
  EntitySpec cube = DynamicBox(2, {0, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  cube.rigid_body->friction = mu;
  EXPECT_TRUE(Add(world, cube).ok());
  auto along = [&](const Vec3f& v) { return v.x * std::cos(yaw) + v.z * std::sin(yaw); };
  auto across = [&](const Vec3f& v) { return -v.x * std::sin(yaw) + v.z * std::cos(yaw); };
  SlopeRun r;
  double v1 = 0;
  const int steps = static_cast<int>(seconds * 60);
  for (int i = 1; i <= steps; ++i) {
    world.Step();
    if (i == 30) v1 = along(Vel(world, 2));
    if (i == 90) r.acceleration = along(Vel(world, 2)) - v1;  // over 1 s
  }
  r.along = along(Pos(world, 2));
  r.across = across(Pos(world, 2));
  return r;
}

// Sliding: a = g (sin - mu cos) along the slope, whatever the direction in the tangent plane
// (the friction disk: two rows each clamped to mu N would allow up to sqrt(2) mu N diagonally).
TEST(ContactSolverTest, PatchFrictionBoxSlidesDownASlopeAtGSinMinusMuCos) {
  const float mu = 0.5f;
  for (const double deg : {35.0, 45.0}) {
    for (const double yaw_deg : {0.0, 30.0, 45.0}) {
      const double th = deg * M_PI / 180.0;
      const double expected = kG * (std::sin(th) - mu * std::cos(th));
      const SlopeRun s = Slope(true, th, yaw_deg * M_PI / 180.0, mu, 1.6);
      const SlopeRun b = Slope(false, th, yaw_deg * M_PI / 180.0, mu, 1.6);
      std::printf("[patch] %.0f deg slope, yaw %.0f deg: a = %.4f m/s^2, g(sin - mu cos) = %.4f, "
                  "across %.1e m (Bullet's friction: %.4f m/s^2, across %.1e m)\n",
                  deg, yaw_deg, s.acceleration, expected, s.across, b.acceleration, b.across);
      EXPECT_NEAR(s.acceleration, expected, 0.03 * expected + 0.02) << deg << " / " << yaw_deg;
      // Sideways: the sliding box rocks on its leading edge (in Bullet's friction too), and the
      // rocking turns the patch centre's velocity by up to ~1.5 degrees (measured 2 % of the path
      // at 30-45 degrees of yaw, Bullet's friction 0.4 %).
      EXPECT_LT(std::abs(s.across), 0.03 * s.along) << "slides off the slope's direction";
    }
  }
}

// Static friction: 3 degrees below the friction angle atan(mu) the box stays (as the suite's
// bound for Bullet's friction: under 2 mm in 2 s); 3 degrees above, it slides.
TEST(ContactSolverTest, PatchFrictionBoxRestsOnASlopeBelowTheFrictionAngle) {
  const float mu = 0.5f;
  const double critical = std::atan(mu);
  const double margin = 3.0 * M_PI / 180.0;
  for (const double yaw_deg : {0.0, 45.0}) {
    const double yaw = yaw_deg * M_PI / 180.0;
    const SlopeRun stick = Slope(true, critical - margin, yaw, mu, 2.0);
    const SlopeRun slide = Slope(true, critical + margin, yaw, mu, 2.0);
    std::printf("[patch] yaw %.0f deg: %.1e m at atan(mu) - 3 deg, %.3f m at + 3 deg\n", yaw_deg,
                stick.along, slide.along);
    EXPECT_LT(std::hypot(stick.along, stick.across), 2e-3) << "creeps below atan(mu)";
    const double a_slide = kG * (std::sin(critical + margin) - mu * std::cos(critical + margin));
    EXPECT_GT(slide.along, 0.5 * (0.5 * a_slide * 4.0)) << "does not slide above atan(mu)";
  }
}

// A cube (side a, mass m) spinning about the vertical on its face. How the weight spreads over a
// rigid face is indeterminate; the friction torque lies between uniform pressure (the textbook
// case, mu m g a 0.3826, alpha = 6 * 0.3826 mu g / a with I = m a^2 / 6) and all the weight on
// the four corners (mu m g a 0.7071). Patch friction's twist row models uniform pressure; the
// contact points Bullet's box-box detector keeps while the box turns (some steps 2-3 of the 4
// corners) move the patch centre, so the measured rate lies above it.
struct Spin {
  double alpha = 0;  // rad/s^2, least-squares slope of the spin rate while it is 80 % to 20 %
  double drift = 0;  // m, the box's horizontal travel
  double final_speed = 0;
};

Spin SpinDown(bool patch, float mu, float half, float spin) {
  PhysicsWorld world(Patch(patch));
  EXPECT_TRUE(Add(world, Ground(1, 1.0f)).ok());
  EntitySpec cube = DynamicBox(2, {0, half, 0}, {half, half, half}, 1.0f);
  cube.rigid_body->friction = mu;
  EXPECT_TRUE(Add(world, cube).ok());
  for (int i = 0; i < 30; ++i) world.Step();  // settle (contact impulses established)
  EXPECT_TRUE(world.SetVelocity(2, Vec3f{}, Vec3f{0, spin, 0}).ok());
  const Vec3f start = Pos(world, 2);
  double st = 0, sw = 0, stt = 0, stw = 0, n = 0;
  Vec3f lin, ang;
  for (int i = 1; i <= 120; ++i) {
    world.Step();
    EXPECT_TRUE(world.GetVelocity(2, &lin, &ang).ok());
    if (ang.y < 0.8 * spin && ang.y > 0.2 * spin) {
      const double t = i / 60.0;
      st += t, sw += ang.y, stt += t * t, stw += t * ang.y, n += 1;
    }
  }
  Spin s;
  s.alpha = n >= 3 ? -(n * stw - st * sw) / (n * stt - st * st) : 0;
  const Vec3f end = Pos(world, 2);
  s.drift = std::hypot(end.x - start.x, end.z - start.z);
  s.final_speed = std::abs(ang.y);
  return s;
}

TEST(ContactSolverTest, PatchFrictionSpinningBoxSlowsWithinTheRigidFaceEnvelope) {
  const float mu = 0.5f;
  for (const float half : {0.25f, 0.5f}) {
    const double a = 2 * half;
    const double uniform = 6.0 * 0.38259 * mu * kG / a;
    const double corners = 6.0 * 0.70711 * mu * kG / a;
    const float spin = 6.0f;
    const Spin patch = SpinDown(true, mu, half, spin);
    const Spin bullet = SpinDown(false, mu, half, spin);
    std::printf("[patch] spin-down, %.1f m cube at %.0f rad/s: alpha %.2f rad/s^2 (uniform "
                "pressure %.2f, corners %.2f; Bullet's per-point friction %.2f), drift %.1e m\n",
                a, spin, patch.alpha, uniform, corners, bullet.alpha, patch.drift);
    EXPECT_GT(patch.alpha, 0.9 * uniform) << a;
    EXPECT_LT(patch.alpha, corners) << a;
    EXPECT_LT(patch.final_speed, 1e-2) << "still spinning after 2 s";
    EXPECT_LT(patch.drift, 0.05 * a) << "a spin about the centre walked the box";
  }
}

// A stack of ten cubes that never sleeps, as the accuracy suite's (60 s; the suite's bound is a
// quarter of a box, 0.25 m; measured 0.16 m with Bullet's friction at 7 iterations): patch
// friction holds it at 4 iterations (0.103 m with its rows solved one at a time, 0.003 m with
// the block solve). Also: the stack's weight reaches the ground (no box sinks).
TEST(ContactSolverTest, PatchFrictionNeverSleepingStackStandsAtFourIterations) {
  PhysicsConfig cfg = Patch(true);
  cfg.sleeping = false;
  cfg.substeps = 4;
  cfg.solver_iterations = 4;
  PhysicsWorld world(cfg);
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  const float h = 0.25f;
  for (uint32_t i = 0; i < 10; ++i) {
    ASSERT_TRUE(Add(world, DynamicBox(10 + i, {0, h + 2 * h * i, 0}, {h, h, h}, 1.0f)).ok());
  }
  double drift = 0;
  for (int s = 0; s < 60 * 60; ++s) {
    world.Step();
    for (uint32_t i = 0; i < 10; ++i) {
      drift = std::max<double>(
          drift, testing::Dist(Pos(world, 10 + i), Vec3f{0, h + 2 * h * static_cast<float>(i), 0}));
    }
  }
  std::printf("[patch] never-sleeping stack, 4 iterations: max drift %.3f m over 60 s\n", drift);
  EXPECT_LT(drift, 0.25);
}

// A never-sleeping 4 x 4 layer of touching 0.2 m boxes on the ground and nothing else: no force
// pushes it sideways, so every box should stay where it was put. Returns the largest distance a
// box moved from its start, sampled every second. Measured (docs/benchmarks.md, "Full stir,
// sessions 13 and 14"), 5 s / 20 s: Bullet's per-point friction (7 iterations) 0.012 / 0.043 mm;
// patch friction 2.09 / 9.74 mm and growing (the boxes rock with a growing amplitude).
float NeverSleepingLayerDrift(bool patch_friction, int steps) {
  PhysicsConfig cfg;
  cfg.sleeping = false;
  cfg.patch_friction = patch_friction;
  if (!patch_friction) cfg.solver_iterations = 7;  // Bullet's friction as measured above
  PhysicsWorld world(cfg);
  EXPECT_TRUE(Add(world, Ground(1)).ok());
  std::vector<Vec3f> start;
  for (int i = 0; i < 4; ++i) {
    for (int k = 0; k < 4; ++k) {
      start.push_back(Vec3f{0.2f * i, 0.1f, 0.2f * k});
      EXPECT_TRUE(Add(world, DynamicBox(100 + 4 * i + k, start.back(), {0.1f, 0.1f, 0.1f}, 1.0f))
                      .ok());
    }
  }
  float worst = 0;
  for (int i = 1; i <= steps; ++i) {
    world.Step();
    if (i % 60 != 0 && i != steps) continue;
    for (uint32_t j = 0; j < start.size(); ++j) {
      worst = std::max(worst, testing::Dist(Pos(world, 100 + j), start[j]));
    }
  }
  std::printf("[layer] patch friction %d: worst drift %.4f mm in %.0f s\n", patch_friction ? 1 : 0,
              worst * 1e3, steps / 60.0);
  return worst;
}

TEST(ContactSolverTest, NeverSleepingLayerOfTouchingBoxesStaysPutWithBulletFriction) {
  EXPECT_LT(NeverSleepingLayerDrift(false, 300), 0.0005f);
}

}  // namespace
}  // namespace edgephys::physics
