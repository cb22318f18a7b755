// Headless scenes for benchmarks (bench/, loadgen) and tests: Decoupled Edge Physics'
// "MultiObject" scene (N boxes dropped into a walled container, a kinematic paddle stirring
// them so that a good
// share keeps moving) built twice from the same parameters: once through PhysicsWorld from
// containers (what PhyS runs), once directly in raw Bullet (the baseline), so that a benchmark
// can step both side by side and quote the PhysicsWorld overhead as a ratio. Plus a "bunny-like"
// soft body generator (Decoupled Edge Physics' Softbody scenario uses ~500 particles per bunny).
//
// Thread-safety: each scene object is used by one thread. Cost: construction O(N); Step() is
// one physics step (PhyS variant: plus CollectStates/DrainEvents as the relay would call them).
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

#include "physics_backend/container_builder.h"
#include "physics_backend/physics_world.h"

class btDefaultMotionState;

namespace edgephys::physics {

struct MultiObjectParams {
  int num_objects = 500;
  float box_half_extent = 0.1f;       // m
  float box_mass = 1.0f;              // kg
  float friction = 0.5f;
  float restitution = 0.1f;
  float wall_height = 1.5f;           // m
  float stirrer_angular_speed = 1.5f; // rad/s about +Y
  float stirrer_reach = 0.95f;        // paddle half length, as a fraction of the half width
  float layers = 3.0f;                // container floor sized for this many layers (60% packing)
  float stirrer_center_y = 0.4f;      // m; the pile is ~0.6 m deep (3 layers of 0.2 m boxes)
  float stirrer_half_height = 0.4f;   // m; 0.4 at 0.4 spans the whole pile
  uint32_t seed = 1;
  PhysicsConfig config;               // PhyS settings; raw Bullet takes only dt and gravity
};

// Entity ids used by the scene.
inline constexpr uint32_t kSceneFloorId = 1;      // floor 1, walls 2..5
inline constexpr uint32_t kSceneStirrerId = 6;
inline constexpr uint32_t kSceneFirstBoxId = 100; // boxes 100 .. 100 + N - 1

// Inner half width of the container (m): grows with sqrt(N) so the boxes settle in ~p.layers
// layers.
float MultiObjectHalfWidth(const MultiObjectParams& p);
// Every entity of the scene (floor, walls, stirrer, boxes), deterministic in p.seed.
std::vector<EntitySpec> MultiObjectSpecs(const MultiObjectParams& p);
// The stirrer's pose after `time` seconds.
void StirrerPose(const MultiObjectParams& p, double time, Vec3f* position, Quatf* rotation);

class PhysSMultiObjectScene {
 public:
  explicit PhysSMultiObjectScene(const MultiObjectParams& params);
  // Moves the stirrer (MoveToTransform), steps, collects moved states and drains events.
  void Step();
  PhysicsWorld& world() { return world_; }
  size_t last_moved() const { return moved_.size(); }
  size_t MovingBoxes(float min_speed) const;  // O(N), for tests and reporting

 private:
  MultiObjectParams params_;
  PhysicsWorld world_;
  uint64_t steps_ = 0;
  std::vector<EntityState> moved_;
  std::vector<PhysicsEvent> events_;
};

// The baseline: the same scene in Bullet with every Bullet setting at its default (no CCD,
// Bullet's sleep thresholds and pools, 10 iterations, btDiscreteDynamicsWorld). Only the scene
// itself (shapes, masses, friction, restitution, gravity, dt) is taken from the params;
// params.config's PhyS settings do not apply to it.
class RawBulletMultiObjectScene {
 public:
  explicit RawBulletMultiObjectScene(const MultiObjectParams& params);
  ~RawBulletMultiObjectScene();
  void Step();  // moves the stirrer's motion state and steps Bullet once
  size_t MovingBoxes(float min_speed) const;
  btDiscreteDynamicsWorld* world() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

struct BunnyParams {
  Vec3f center{0.0f, 1.0f, 0.0f};
  float scale = 0.3f;            // body half length (m); the rest is proportional
  int target_particles = 500;
  float total_mass = 1.0f;       // kg
  float stiffness = 200.0f;      // N/m (see PhysicsWorld header for the mapping)
  float damping = 0.05f;
};
// Lattice points inside a bunny-like union (ellipsoid body, sphere head, two ellipsoid ears),
// with the spacing searched so the count is close to target_particles (within ~10%), and springs
// between all lattice neighbours (26-neighbourhood). Deterministic.
SoftBodySpec MakeBunnySoftBody(const BunnyParams& p);

// A 5x5x5 lattice cube: 125 particles of 10 g at 5 cm spacing, the lowest layer 0.3 m up,
// springs between all 26-neighbours, damping 0.05. The soft-body stability tests and the
// stability-envelope report both use it.
SoftBodySpec MakeLatticeCubeSoftBody(float stiffness);

}  // namespace edgephys::physics
