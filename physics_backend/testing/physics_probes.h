// Probes of a PhysicsWorld shared by the physics tests and the physics reports in bench/:
// adding an entity from its spec, reading an entity's position or velocity, a ground slab and
// the bounce experiment. No GoogleTest here: callers check the Status they are handed.
#pragma once

#include <cstdint>
#include <vector>

#include "physics_backend/container_builder.h"
#include "physics_backend/physics_world.h"

namespace edgephys::physics::testing {

// Adds `spec` (built into a container); the world's Status, and why it refused in *reason.
inline Status Add(PhysicsWorld& world, const EntitySpec& spec, InvalidReason* reason = nullptr) {
  const std::vector<uint8_t> buf = BuildContainer(spec);
  return world.AddEntity(AsContainer(buf), reason);
}

// Entity `id`'s position (m); zero if there is no such entity.
inline Vec3f Pos(const PhysicsWorld& world, uint32_t id) {
  EntityState s;
  (void)world.GetState(id, &s);
  return s.position;
}

// Entity `id`'s linear velocity (m/s); zero if there is no such entity.
inline Vec3f Vel(const PhysicsWorld& world, uint32_t id) {
  Vec3f lin, ang;
  (void)world.GetVelocity(id, &lin, &ang);
  return lin;
}

// A static ground slab with its top face at y = 0, `half` m from the origin along x and z.
inline EntitySpec Ground(uint32_t id, float friction = 0.5f, float restitution = 0.0f,
                         float half = 50.0f) {
  EntitySpec g = StaticBox(id, {0, -0.5f, 0}, {half, 0.5f, half});
  g.rigid_body = RigidBodySpec{};
  g.rigid_body->mass = 0;
  g.rigid_body->friction = friction;
  g.rigid_body->restitution = restitution;
  return g;
}

// The ten-box stack: 1 kg cubes 0.5 m wide, ids 10 to 19 from the bottom, stacked in exact
// contact from y = 0 up, on a Ground (id 1, friction 0.5).
struct BoxStack {
  std::vector<EntitySpec> specs;  // the ground, then the boxes from the bottom
  std::vector<Vec3f> start;       // the boxes' initial positions: start[i] is id 10 + i's
};

inline BoxStack MakeBoxStack() {
  constexpr float h = 0.25f;
  BoxStack stack;
  stack.specs.push_back(Ground(1, 0.5f));
  for (uint32_t i = 0; i < 10; ++i) {
    stack.start.push_back({0, h + 2 * h * static_cast<float>(i), 0});
    stack.specs.push_back(DynamicBox(10 + i, stack.start.back(), {h, h, h}, 1.0f));
  }
  return stack;
}

struct BounceRun {
  Status added;                 // adding the ground and the ball; heights is empty if not ok
  std::vector<double> heights;  // apex heights (m, the ball's bottom above the ground), h0 first
};

// The bounce experiment: a sphere (r 0.1 m, 1 kg, restitution `e`) dropped with its bottom `h0`
// m above a restitution-1 ground (Bullet multiplies restitutions, so the pair's is `e`), stepped
// under `cfg` (gravity 9.81 m/s^2 down) at most `max_steps` times. Each apex is interpolated
// between the two samples around it with the ballistic parabola. Stops after `apexes` heights
// or at the first apex under `min_height` (not recorded).
inline BounceRun BounceApexes(const PhysicsConfig& cfg, float e, float h0, int apexes,
                              double min_height, int max_steps) {
  constexpr double kG = 9.81;
  BounceRun run;
  PhysicsWorld world(cfg);
  const float r = 0.1f;
  run.added = Add(world, Ground(1, 0.5f, 1.0f));
  if (!run.added.ok()) return run;
  EntitySpec ball = DynamicSphere(2, {0, h0 + r, 0}, r, 1.0f);
  ball.rigid_body->restitution = e;
  run.added = Add(world, ball);
  if (!run.added.ok()) return run;
  run.heights.push_back(h0);
  const double dt = cfg.fixed_dt;
  double prev_vy = 0;
  bool rising = false;
  for (int i = 0; i < max_steps && static_cast<int>(run.heights.size()) < apexes; ++i) {
    world.Step();
    const double vy = Vel(world, 2).y;
    if (prev_vy < 0 && vy > 0) rising = true;
    if (rising && prev_vy > 0 && vy <= 0) {
      // v = 0 at dt * prev_vy / (prev_vy - vy) after the previous sample; the parabola peaks
      // above the current sample by g/2 * (time from the peak)^2.
      const double t_peak = dt * prev_vy / (prev_vy - vy);
      const double y = Pos(world, 2).y - r + 0.5 * kG * (dt - t_peak) * (dt - t_peak);
      if (y < min_height) break;
      run.heights.push_back(y);
      rising = false;
    }
    prev_vy = vy;
  }
  return run;
}

}  // namespace edgephys::physics::testing
