// PhysicsSettings: every tunable of one PhysicsWorld (PhyS), fixed when the world is built.
// One line per field: meaning, unit, default, and what it costs or saves. Figures behind the
// defaults are on docs/benchmarks.md ("PhyS: model no more than the scene needs").
// Units: metres, seconds, kilograms, radians. Plain value type; copy freely.
#pragma once

#include <cstddef>
#include <cstdint>

#include "protocol/state_codec.h"

namespace edgephys::physics {

inline constexpr float kBulletAabbMargin = 0.02f;  // Bullet's gContactBreakingThreshold (m)

struct PhysicsSettings {
  // --- Stepping
  float fixed_dt = 1.0f / 60.0f;  // s per Step(); a lower rate fails the accuracy suite
  int substeps = 1;               // Bullet steps per Step() (each fixed_dt / substeps); cost x substeps; tall stacks need > 1
  int max_substeps = 4;           // Advance(): most fixed steps per call; a longer backlog is dropped
  Vec3f gravity{0.0f, -9.81f, 0.0f};  // m/s^2, room frame
  bool soft_body_world = true;    // btSoftRigidDynamicsWorld; false: btDiscreteDynamicsWorld, soft-body containers rejected
  float world_half_extent = 1000.0f;  // m: world bounds, an axis-aligned cube about the origin (kAxisSweep's range)

  // --- Solver
  int solver_iterations = 7;      // per substep; each is ~1.5-3 % of a busy step; fewer than 7 fail the suite with one friction row
  enum class Solver : uint8_t { kSequentialImpulse, kNNCG };  // projected Gauss-Seidel / nonlinear conjugate gradient
  Solver solver = Solver::kSequentialImpulse;  // kNNCG fails a restitution or stick-slip bound at 7 iterations
  bool split_impulse = false;     // separate position-only penetration pass (Bullet: on); off is one pass fewer per iteration
  bool randomize_solver_order = false;  // shuffle rows every iteration; ~+10 % step time
  float warmstarting_factor = 0.85f;    // share of last step's impulses the first iteration starts from (0: none)
  float solver_residual_threshold = 0.0f;  // stop iterating below this squared residual (0: always solver_iterations)
  bool split_islands = false;     // one solver call per island (Bullet's default); false: one call for all, ~3 % cheaper
  bool two_friction_directions = false;      // a second friction row per point (SOLVER_USE_2_FRICTION_DIRECTIONS)
  bool friction_direction_caching = false;   // keep a contact's friction directions (needs the two above and below)
  bool velocity_dependent_friction = true;   // first friction direction follows the sliding velocity; false: fixed basis
  bool interleave_friction = false;          // friction rows right after their normal row; converges worse
  bool patch_friction = false;    // contact_solver.h: per manifold 2 tangent rows on a friction disk + 1 twist row; sequential impulse only; 7 rows per 4-point box pair instead of 8

  // --- Collision detection
  enum class Broadphase : uint8_t { kDbvt, kAxisSweep };  // AABB trees / sweep and prune over world_half_extent
  Broadphase broadphase = Broadphase::kAxisSweep;  // kAxisSweep: cheap for coherent motion; ~150 B per slot, capacity doubles from 1,024
  float aabb_margin = 0.005f;     // m a dynamic body's AABB is grown by (Bullet: 0.02); smaller: fewer pairs, too small finds pairs a step late
  float aabb_hysteresis = 0.0f;   // m of extra AABB the broadphase keeps until the body leaves it (0: off)
  int contact_pool_size = 256;    // manifolds and algorithms preallocated per world (~0.23 MB at 256); beyond: malloc per new pair; min 64
  float contact_processing_threshold = 1e18f;  // m: points farther apart get no solver row (default: all)
  float contact_distance = 0.005f;  // m: a manifold point closer than this counts as touching
  bool ccd = true;                // sweep small fast bodies (keeps stirred boxes in their container); ~8 % of a busy step
  float ccd_motion_fraction = 0.5f;        // sweep when a body moves more than this x its smallest half extent per step
  float ccd_swept_radius_fraction = 0.9f;  // swept sphere radius, x the smallest half extent
  bool ccd_static_only = false;   // sweeps test static/kinematic bodies only; lets fast boxes escape a stir

  // --- Sleeping and resting (rest_manager.h)
  bool sleeping = true;           // false: bodies never deactivate (and nothing is frozen)
  float sleep_linear_threshold = 0.1f;   // m/s below which (with the angular one) an island may sleep
  float sleep_angular_threshold = 0.1f;  // rad/s
  float deactivation_time = 2.0f;        // s below both before sleeping (Bullet: 2); O(active bodies) per step when not 2
  bool rest_freeze = true;        // freeze resting bodies (made static until woken; see rest_manager.h); no solver rows or narrowphase for them
  float rest_linear_threshold = 0.1f;    // m/s below which (with the angular one) a body counts as resting
  float rest_angular_threshold = 0.2f;   // rad/s
  float rest_time = 0.5f;                // s resting before freezing; drift cut off: at most rest_linear_threshold x rest_time
  float rest_wake_margin = 0.05f;        // m: look-ahead around a frozen body's AABB that wakes it
  float rest_wake_delta_v = 0.33f;       // m/s: a contact impulse / mass above this wakes it (~2 g dt)

  // --- Stability guard (stability_guard.cc)
  float max_linear_speed = 200.0f;     // m/s above which a rigid body is reset
  float max_angular_speed = 1000.0f;   // rad/s above which a rigid body is reset
  float soft_max_node_speed = 100.0f;  // m/s above which a soft body is reset
  float soft_max_extent_ratio = 4.0f;  // AABB diagonal over the one when added above which a soft body is reset
  int soft_soften_after_resets = 3;    // consecutive resets before a soft body's kLST is clamped to 1

  // --- Soft bodies
  int soft_iterations = 4;               // position solver iterations (Bullet piterations); cost x iterations
  float soft_max_link_stiffness = 1.0f;  // clamp for the derived kLST (<= 1 stable, > 2 diverges)
  float soft_margin = 0.02f;             // m: collision margin of soft bodies

  // --- Grab drive (velocity control towards the MoveToTransform target)
  float grab_gain = 1.0f;                // fraction of the pose error removed per step
  float grab_max_speed = 10.0f;          // m/s
  float grab_max_angular_speed = 20.0f;  // rad/s
  float release_velocity_window_s = 0.1f;  // s of hand poses a release velocity is estimated from (pose_history.h; 0: drive's last step); ~300 B per driven entity

  // --- Validation limits (per container; beyond them AddEntity fails with a Status)
  size_t max_colliders = 64;
  size_t max_mesh_vertices = 65536;
  size_t max_mesh_triangles = 131072;
  size_t max_soft_nodes = 4096;
  size_t max_soft_springs = 65536;
  size_t max_joints = 16;
  size_t max_pending_events = 65536;  // undrained events beyond this are dropped and counted
};

// The name callers use.
using PhysicsConfig = PhysicsSettings;

}  // namespace edgephys::physics
