// Soft bodies: the stability envelope over stiffness x time step x solver iterations, the guard
// recovering every explosion, and the bunny-like generator.
#include <BulletSoftBody/btSoftBody.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>

#include "physics_backend/testing/physics_test_util.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {
namespace {

using testing::Add;
using testing::Ground;
using testing::OneNonFiniteGuardReset;

struct EnvelopeCell {
  double klst = 0;        // stiffness * dt^2 * 2 / m before clamping
  uint64_t resets = 0;
  uint64_t softened = 0;
  bool nan_escaped = false;
  double extent_ratio = 0;  // final AABB diagonal / initial
};

EnvelopeCell RunCell(float stiffness, float dt, int iterations, float max_link_stiffness) {
  PhysicsConfig cfg;
  cfg.fixed_dt = dt;
  cfg.soft_iterations = iterations;
  cfg.soft_max_link_stiffness = max_link_stiffness;
  PhysicsWorld world(cfg);
  EXPECT_TRUE(Add(world, Ground(1)).ok());
  EntitySpec e;
  e.id = 2;
  e.soft_body = MakeLatticeCubeSoftBody(stiffness);
  EXPECT_TRUE(Add(world, e).ok());
  EnvelopeCell cell;
  cell.klst = stiffness * dt * dt * 2.0 / 0.01;
  const double diag0 = std::sqrt(3.0) * 0.2;
  std::vector<Vec3f> nodes;
  std::vector<EntityState> moved;
  const int steps = static_cast<int>(1.0f / dt);  // 1 simulated second
  for (int i = 0; i < steps; ++i) {
    world.Step();
    world.CollectStates(&moved);
    for (const EntityState& s : moved) cell.nan_escaped |= !IsValidState(s);
    (void)world.GetSoftBodyNodes(2, &nodes);
    for (const Vec3f& p : nodes) {
      cell.nan_escaped |= !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
    }
  }
  Vec3f mn{1e9f, 1e9f, 1e9f}, mx{-1e9f, -1e9f, -1e9f};
  for (const Vec3f& p : nodes) {
    mn = {std::min(mn.x, p.x), std::min(mn.y, p.y), std::min(mn.z, p.z)};
    mx = {std::max(mx.x, p.x), std::max(mx.y, p.y), std::max(mx.z, p.z)};
  }
  cell.extent_ratio = testing::Dist(mn, mx) / diag0;
  cell.resets = world.counters().guard_resets;
  cell.softened = world.counters().soft_softened;
  return cell;
}

TEST(SoftBodyTest, StabilityEnvelopeAndGuardRecoversEveryExplosion) {
  const float stiffness[] = {20, 200, 2000, 20000};
  const float dts[] = {1.0f / 120, 1.0f / 60, 1.0f / 30};
  const int iterations[] = {1, 4, 10};
  std::printf("[soft envelope] unclamped kLST = k dt^2 2/m; resets (softened) / final extent ratio\n");
  std::printf("%8s %8s %5s %9s %8s %9s %8s\n", "k N/m", "dt", "iter", "kLST", "resets",
              "softened", "extent");
  int exploded_cells = 0;
  for (float k : stiffness) {
    for (float dt : dts) {
      for (int it : iterations) {
        const EnvelopeCell c = RunCell(k, dt, it, 1e9f);
        std::printf("%8.0f %8.4f %5d %9.3f %8llu %9llu %8.2f\n", k, dt, it, c.klst,
                    static_cast<unsigned long long>(c.resets),
                    static_cast<unsigned long long>(c.softened), c.extent_ratio);
        EXPECT_FALSE(c.nan_escaped) << k << " " << dt << " " << it;
        // Whatever happened, the guard left the body within its extent threshold.
        EXPECT_LT(c.extent_ratio, 4.0) << k << " " << dt << " " << it;
        if (c.klst <= 0.5) {
          EXPECT_EQ(c.resets, 0u) << "stable regime exploded";
        }
        if (c.klst >= 8.0) {
          EXPECT_GT(c.resets, 0u) << "over-relaxed regime did not explode";
        }
        if (c.resets > 0) ++exploded_cells;
      }
    }
  }
  EXPECT_GT(exploded_cells, 0);
  // The default clamp (kLST <= 1) removes the explosions everywhere on the same grid.
  for (float k : stiffness) {
    for (float dt : dts) {
      const EnvelopeCell c = RunCell(k, dt, 10, 1.0f);
      EXPECT_EQ(c.resets, 0u) << "clamped k=" << k << " dt=" << dt;
      EXPECT_FALSE(c.nan_escaped);
    }
  }
}

TEST(SoftBodyTest, GuardRestoresInjectedNaN) {
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  EntitySpec e;
  e.id = 2;
  e.soft_body = MakeLatticeCubeSoftBody(200);
  ASSERT_TRUE(Add(world, e).ok());
  for (int i = 0; i < 5; ++i) world.Step();
  btSoftBody* sb = world.SoftBodyForTesting(2);
  ASSERT_NE(sb, nullptr);
  sb->m_nodes[7].m_v = btVector3(std::numeric_limits<float>::quiet_NaN(), 0, 0);
  world.Step();
  ASSERT_TRUE(OneNonFiniteGuardReset(world, 2));
  std::vector<Vec3f> nodes;
  ASSERT_TRUE(world.GetSoftBodyNodes(2, &nodes).ok());
  for (const Vec3f& p : nodes) EXPECT_TRUE(std::isfinite(p.x + p.y + p.z));
  for (int i = 0; i < 120; ++i) world.Step();
  EXPECT_EQ(world.counters().guard_resets, 1u);
}

TEST(SoftBodyTest, BunnyHasAboutFiveHundredParticlesAndLandsStably) {
  BunnyParams p;
  p.center = {0, 0.6f, 0};
  const SoftBodySpec bunny = MakeBunnySoftBody(p);
  const size_t n = bunny.particles.size() / 3;
  std::printf("[bunny] %zu particles, %zu springs\n", n, bunny.springs.size() / 2);
  EXPECT_GE(n, 450u);
  EXPECT_LE(n, 550u);
  EXPECT_EQ(bunny.masses.size(), n);
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  EntitySpec e;
  e.id = 2;
  e.soft_body = bunny;
  ASSERT_TRUE(Add(world, e).ok());
  for (int i = 0; i < 120; ++i) world.Step();
  std::vector<Vec3f> nodes;
  ASSERT_TRUE(world.GetSoftBodyNodes(2, &nodes).ok());
  float min_y = 1e9f;
  for (const Vec3f& q : nodes) min_y = std::min(min_y, q.y);
  std::printf("[bunny] lowest particle %.3f m after 2 s (ground at 0)\n", min_y);
  // Nodes rest on the soft margin (0.02 m): with kKHR = 1 (full penetration removal against
  // static bodies) and 1/240 s substeps it measures +0.017 m; before (kKHR 0.1, one 1/60 s
  // step) the lattice sank 0.109 m into the ground.
  EXPECT_GT(min_y, -0.02f);  // sinks less than 2 cm
  EXPECT_LT(min_y, 0.03f);   // and did land (margin + 1 cm)
  EXPECT_EQ(world.counters().guard_resets, 0u);
}

// A kinematic plate squashes a landed bunny to 60 % of its height and holds it there.
struct PressedBunny {
  PhysicsWorld world;
  SoftBodySpec bunny;
  float plate_y = 0;
  static constexpr uint32_t kBunny = 2, kPlate = 3;
  static constexpr float kPlateHalf = 0.05f;

  PressedBunny() {
    BunnyParams p;
    p.center = {0, 0.6f, 0};
    bunny = MakeBunnySoftBody(p);
    EXPECT_TRUE(Add(world, Ground(1)).ok());
    EntitySpec e;
    e.id = kBunny;
    e.soft_body = bunny;
    EXPECT_TRUE(Add(world, e).ok());
    plate_y = 1.5f;
    EXPECT_TRUE(Add(world, Plate(plate_y)).ok());
  }
  static EntitySpec Plate(float y) {
    EntitySpec plate = StaticBox(kPlate, {0, y, 0}, {1, kPlateHalf, 1});
    plate.rigid_body = RigidBodySpec{};
    plate.rigid_body->kinematic = true;
    plate.rigid_body->mass = 0;
    return plate;
  }
  float Top() {
    std::vector<Vec3f> nodes;
    EXPECT_TRUE(world.GetSoftBodyNodes(kBunny, &nodes).ok());
    float top = -1e9f;
    for (const Vec3f& q : nodes) top = std::max(top, q.y);
    return top;
  }
  // Lands (1 s), then lowers the plate at 0.3 m/s until its face is at 60 % of the bunny's
  // height, then holds it for `hold_s`.
  void Squash(float hold_s) {
    for (int i = 0; i < 60; ++i) world.Step();
    const float target = 0.6f * Top() + kPlateHalf;
    const float dy = 0.3f * world.config().fixed_dt;
    while (plate_y > target) {
      plate_y = std::max(target, plate_y - dy);
      EXPECT_TRUE(world.MoveToTransform(kPlate, {0, plate_y, 0}, {}).ok());
      world.Step();
    }
    Hold(hold_s);
  }
  void Hold(float seconds) {
    const int steps = static_cast<int>(seconds / world.config().fixed_dt);
    for (int i = 0; i < steps; ++i) {
      EXPECT_TRUE(world.MoveToTransform(kPlate, {0, plate_y, 0}, {}).ok());
      world.Step();
    }
  }
};

float MaxNodeDistance(const std::vector<Vec3f>& a, const std::vector<Vec3f>& b) {
  EXPECT_EQ(a.size(), b.size());
  float worst = 0;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    worst = std::max(worst, testing::Dist(a[i], b[i]));
  }
  return worst;
}

// Failover restore (issue 15): a fresh world given the relay's last particles keeps the body as
// it was, squashed under the plate, instead of starting again from the spawn shape.
TEST(SoftBodyTest, RestoredNodesKeepTheDeformationOnAFreshWorld) {
  PressedBunny original;
  original.Squash(3.0f);
  std::vector<Vec3f> before;
  ASSERT_TRUE(original.world.GetSoftBodyNodes(PressedBunny::kBunny, &before).ok());
  const float rest_top = 0.6f + 0.3f;  // well above the squashed top
  ASSERT_LT(original.Top(), rest_top - 0.1f) << "the plate did not squash the bunny";

  // The fresh world: same containers, the plate where it holds, the particles restored (or
  // not: what failover did before), then `steps` steps with the plate still holding.
  auto rebuild = [&](bool restore, int steps, float* top) {
    PhysicsWorld fresh;
    EXPECT_TRUE(Add(fresh, Ground(1)).ok());
    EntitySpec e;
    e.id = PressedBunny::kBunny;
    e.soft_body = original.bunny;
    EXPECT_TRUE(Add(fresh, e).ok());
    EXPECT_TRUE(Add(fresh, PressedBunny::Plate(original.plate_y)).ok());
    if (restore) {
      EXPECT_TRUE(fresh.SetSoftBodyNodes(PressedBunny::kBunny, 0, before).ok());
    }
    for (int i = 0; i < steps; ++i) fresh.Step();
    std::vector<Vec3f> after;
    EXPECT_TRUE(fresh.GetSoftBodyNodes(PressedBunny::kBunny, &after).ok());
    EXPECT_EQ(fresh.counters().guard_resets, 0u);
    if (top != nullptr) {
      *top = -1e9f;
      for (const Vec3f& q : after) *top = std::max(*top, q.y);
    }
    return after;
  };
  // What a receiver sees first after the failover (the new world's first report, one step on)
  // against the last it saw before: the body where it was, not back at its spawn shape.
  const float restored = MaxNodeDistance(before, rebuild(true, 1, nullptr));
  const float from_spawn = MaxNodeDistance(before, rebuild(false, 1, nullptr));
  // Half a second on, it is still squashed, and still follows the original's slow creep under
  // the plate (the restore has no particle velocities: they start at rest).
  float top_later = 0;
  const std::vector<Vec3f> later = rebuild(true, 30, &top_later);
  original.Hold(0.5f);
  std::vector<Vec3f> continued;
  ASSERT_TRUE(original.world.GetSoftBodyNodes(PressedBunny::kBunny, &continued).ok());
  std::printf("[restore] max particle offset one step after the restore: %.4f m (from the spawn "
              "shape: %.4f m); 0.5 s later: the original moved %.4f m, the restored body is "
              "%.4f m from it\n",
              restored, from_spawn, MaxNodeDistance(before, continued),
              MaxNodeDistance(continued, later));
  EXPECT_LT(restored, 0.01f);
  EXPECT_GT(from_spawn, 0.05f);
  EXPECT_LT(top_later, rest_top - 0.1f) << "the restored body sprang back to its rest shape";
  EXPECT_LT(MaxNodeDistance(continued, later), 0.05f);
}

TEST(SoftBodyTest, SetSoftBodyNodesRefusesBadInputAndChangesNothing) {
  PressedBunny b;
  std::vector<Vec3f> nodes, after;
  ASSERT_TRUE(b.world.GetSoftBodyNodes(PressedBunny::kBunny, &nodes).ok());
  const uint32_t n = static_cast<uint32_t>(nodes.size());
  std::vector<Vec3f> one = {Vec3f{0, 1, 0}};
  EXPECT_EQ(b.world.SetSoftBodyNodes(99, 0, one).code(), StatusCode::kNotFound);
  EXPECT_EQ(b.world.SetSoftBodyNodes(1, 0, one).code(), StatusCode::kNotFound);  // rigid
  EXPECT_EQ(b.world.SetSoftBodyNodes(PressedBunny::kBunny, n, one).code(),
            StatusCode::kInvalidArgument);
  EXPECT_EQ(b.world.SetSoftBodyNodes(PressedBunny::kBunny, 0xffffffffu, one).code(),
            StatusCode::kInvalidArgument);
  std::vector<Vec3f> too_many(n + 1, Vec3f{0, 1, 0});
  EXPECT_EQ(b.world.SetSoftBodyNodes(PressedBunny::kBunny, 0, too_many).code(),
            StatusCode::kInvalidArgument);
  std::vector<Vec3f> nan = nodes;
  nan[n / 2].y = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(b.world.SetSoftBodyNodes(PressedBunny::kBunny, 0, nan).code(),
            StatusCode::kInvalidArgument);
  // Finite but beyond the world bounds (Bullet's sparse SDF indexes cells with int casts).
  std::vector<Vec3f> far = nodes;
  far[n / 2].x = 1e30f;
  EXPECT_EQ(b.world.SetSoftBodyNodes(PressedBunny::kBunny, 0, far).code(),
            StatusCode::kInvalidArgument);
  ASSERT_TRUE(b.world.GetSoftBodyNodes(PressedBunny::kBunny, &after).ok());
  EXPECT_EQ(MaxNodeDistance(nodes, after), 0.0f);
  // A chunk in the middle moves only its particles.
  std::vector<Vec3f> chunk(3, Vec3f{0.1f, 0.7f, 0.1f});
  ASSERT_TRUE(b.world.SetSoftBodyNodes(PressedBunny::kBunny, 10, chunk).ok());
  ASSERT_TRUE(b.world.GetSoftBodyNodes(PressedBunny::kBunny, &after).ok());
  for (uint32_t i = 0; i < n; ++i) {
    const bool in_chunk = i >= 10 && i < 13;
    EXPECT_EQ(testing::Dist(after[i], in_chunk ? chunk[0] : nodes[i]), 0.0f) << i;
  }
}

}  // namespace
}  // namespace edgephys::physics
