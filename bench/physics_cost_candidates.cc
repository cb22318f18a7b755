#include "bench/physics_cost_candidates.h"

namespace edgephys::physics {
namespace {

// The "combo-broad" candidates' shared part: axis-sweep broadphase, CCD by size, a larger
// contact pool, Bullet's sleep thresholds, and deactivation after 0.5 s.
void BroadCombo(PhysicsConfig& c) {
  c.broadphase = PhysicsConfig::Broadphase::kAxisSweep;
  c.ccd_motion_fraction = 1.0f;
  c.contact_pool_size = 32768;
  c.sleep_linear_threshold = 0.8f;
  c.sleep_angular_threshold = 1.0f;
  c.deactivation_time = 0.5f;
}

// The settings PhyS shipped before this measurement (its old defaults); every single-setting
// candidate changes one thing from here.
void OldDefaults(PhysicsConfig& c) {
  c = PhysicsConfig{};
  c.rest_freeze = false;  // resting regions came after this measurement
  c.solver_iterations = 10;
  c.sleep_linear_threshold = 0.1f;
  c.sleep_angular_threshold = 0.1f;
  c.deactivation_time = 2.0f;
  c.broadphase = PhysicsConfig::Broadphase::kDbvt;
  c.split_impulse = true;
  c.randomize_solver_order = false;
  c.warmstarting_factor = 0.85f;
  c.solver_residual_threshold = 0;
  c.contact_pool_size = 4096;
  c.contact_processing_threshold = 1e18f;
  c.ccd = true;
  c.ccd_motion_fraction = 0.5f;
}

// The earlier defaults (before the solver candidates), to change one setting from in the
// session-11 rows whatever the current defaults are.
PhysicsConfig& S8Defaults(PhysicsConfig& c) {
  c = PhysicsConfig{};
  c.solver_iterations = 7;
  c.split_impulse = false;
  c.broadphase = PhysicsConfig::Broadphase::kAxisSweep;
  c.rest_freeze = true;
  c.ccd = true;
  c.ccd_motion_fraction = 0.5f;
  c.solver = PhysicsConfig::Solver::kSequentialImpulse;
  c.split_islands = true;
  c.two_friction_directions = false;
  c.friction_direction_caching = false;
  c.velocity_dependent_friction = true;
  c.interleave_friction = false;
  c.ccd_static_only = false;
  c.fixed_dt = 1.0f / 60.0f;
  c.aabb_margin = kBulletAabbMargin;
  c.aabb_hysteresis = 0;
  c.patch_friction = false;
  return c;
}

// Two friction rows per contact with the directions of the step that created the contact.
PhysicsConfig& TwoCachedFrictionDirs(PhysicsConfig& c) {
  c.two_friction_directions = true;
  c.friction_direction_caching = true;
  c.velocity_dependent_friction = false;
  return c;
}

// The current defaults, to change one setting from.
PhysicsConfig& NewWith(PhysicsConfig& c) {
  c = PhysicsConfig{};
  return c;
}

}  // namespace

std::vector<Candidate> Candidates() {
  using B = PhysicsConfig::Broadphase;
  auto from_old = [](std::function<void(PhysicsConfig&)> f) {
    return [f](PhysicsConfig& c) {
      OldDefaults(c);
      f(c);
    };
  };
  return {
      {"old-defaults", from_old([](PhysicsConfig&) {})},
      {"bullet-sleep", from_old([](PhysicsConfig& c) {
         c.sleep_linear_threshold = 0.8f;
         c.sleep_angular_threshold = 1.0f;
       })},
      {"deact-0.5s", from_old([](PhysicsConfig& c) { c.deactivation_time = 0.5f; })},
      {"pools-32k", from_old([](PhysicsConfig& c) { c.contact_pool_size = 32768; })},
      {"axis-sweep", from_old([](PhysicsConfig& c) {
         c.broadphase = B::kAxisSweep;
         c.world_half_extent = 50.0f;
       })},
      {"iter-5", from_old([](PhysicsConfig& c) { c.solver_iterations = 5; })},
      {"iter-5-random", from_old([](PhysicsConfig& c) {
         c.solver_iterations = 5;
         c.randomize_solver_order = true;
       })},
      {"split-off", from_old([](PhysicsConfig& c) { c.split_impulse = false; })},
      {"no-warmstart", from_old([](PhysicsConfig& c) { c.warmstarting_factor = 0; })},
      {"residual-1e-5", from_old([](PhysicsConfig& c) { c.solver_residual_threshold = 1e-5f; })},
      {"contact-proc-0", from_old([](PhysicsConfig& c) { c.contact_processing_threshold = 0; })},
      {"ccd-off", from_old([](PhysicsConfig& c) { c.ccd = false; })},
      {"ccd-by-size", from_old([](PhysicsConfig& c) { c.ccd_motion_fraction = 1.0f; })},
      {"combo-broad", from_old([](PhysicsConfig& c) {
         BroadCombo(c);
       })},
      {"combo-broad-iter5", from_old([](PhysicsConfig& c) {
         BroadCombo(c);
         c.solver_iterations = 5;
       })},
      {"combo-broad-iter5-nosplit", from_old([](PhysicsConfig& c) {
         BroadCombo(c);
         c.solver_iterations = 5;
         c.split_impulse = false;
       })},
      {"iter-7", from_old([](PhysicsConfig& c) { c.solver_iterations = 7; })},
      {"combo-iter7", from_old([](PhysicsConfig& c) {
         c.broadphase = B::kAxisSweep;
         c.ccd_motion_fraction = 1.0f;
         c.split_impulse = false;
         c.solver_iterations = 7;
       })},
      {"new-defaults", [](PhysicsConfig& c) { c = PhysicsConfig{}; }},
      // The defaults with Bullet's own pool size (4,096 manifolds and algorithms preallocated,
      // ~3.6 MB per world) instead of PhyS's 256: what the smaller pool costs a busy scene.
      {"pools-4096", [](PhysicsConfig& c) {
         c = PhysicsConfig{};
         c.contact_pool_size = 4096;
       }},
      // Resting regions (rest_manager.h): the defaults with freezing off, and variants.
      {"no-rest", [](PhysicsConfig& c) {
         c = PhysicsConfig{};
         c.rest_freeze = false;
       }},
      {"rest-0.25s", [](PhysicsConfig& c) {
         c = PhysicsConfig{};
         c.rest_time = 0.25f;
       }},
      {"rest-1s", [](PhysicsConfig& c) {
         c = PhysicsConfig{};
         c.rest_time = 1.0f;
       }},
      {"rest-tight", [](PhysicsConfig& c) {  // thresholds halved
         c = PhysicsConfig{};
         c.rest_linear_threshold = 0.05f;
         c.rest_angular_threshold = 0.1f;
       }},
      {"rest-margin-2cm", [](PhysicsConfig& c) {
         c = PhysicsConfig{};
         c.rest_wake_margin = 0.02f;
       }},
      // The full stir (issue 15, item 1): candidates on top of the defaults.
      {"new-ccd-by-size", [](PhysicsConfig& c) { NewWith(c).ccd_motion_fraction = 1.0f; }},
      {"new-ccd-off", [](PhysicsConfig& c) { NewWith(c).ccd = false; }},
      {"new-ccd-radius-0.5", [](PhysicsConfig& c) { NewWith(c).ccd_swept_radius_fraction = 0.5f; }},
      {"new-ccd-radius-0.25", [](PhysicsConfig& c) { NewWith(c).ccd_swept_radius_fraction = 0.25f; }},
      // Physics rate: per step these cost what a step costs; compare them per simulated second
      // (the sim_s_ratio column), never by the per-step ratio.
      {"rate-40hz", [](PhysicsConfig& c) { NewWith(c).fixed_dt = 1.0f / 40.0f; }},
      {"rate-30hz", [](PhysicsConfig& c) { NewWith(c).fixed_dt = 1.0f / 30.0f; }},
      // The full stir: solver settings Bullet offers, and CCD against walls only.
      {"s8-defaults", [](PhysicsConfig& c) { S8Defaults(c); }},
      {"iter-6", [](PhysicsConfig& c) { S8Defaults(c).solver_iterations = 6; }},
      {"islands-off", [](PhysicsConfig& c) { S8Defaults(c).split_islands = false; }},
      {"nncg", [](PhysicsConfig& c) { S8Defaults(c).solver = PhysicsConfig::Solver::kNNCG; }},
      {"nncg-iter5", [](PhysicsConfig& c) {
         S8Defaults(c).solver = PhysicsConfig::Solver::kNNCG;
         c.solver_iterations = 5;
       }},
      {"friction-fixed-dir", [](PhysicsConfig& c) {
         S8Defaults(c).velocity_dependent_friction = false;
       }},
      {"friction-2dir-cached", [](PhysicsConfig& c) {
         S8Defaults(c).two_friction_directions = true;
         c.friction_direction_caching = true;
         c.velocity_dependent_friction = false;
       }},
      {"f2-iter5", [](PhysicsConfig& c) {
         TwoCachedFrictionDirs(S8Defaults(c)).solver_iterations = 5;
       }},
      {"f2-iter4", [](PhysicsConfig& c) {
         TwoCachedFrictionDirs(S8Defaults(c)).solver_iterations = 4;
       }},
      {"f2-iter5-islands-off", [](PhysicsConfig& c) {
         TwoCachedFrictionDirs(S8Defaults(c)).solver_iterations = 5;
         c.split_islands = false;
       }},
      {"interleave", [](PhysicsConfig& c) { S8Defaults(c).interleave_friction = true; }},
      {"interleave-iter5", [](PhysicsConfig& c) {
         S8Defaults(c).interleave_friction = true;
         c.solver_iterations = 5;
       }},
      {"ccd-static", [](PhysicsConfig& c) { S8Defaults(c).ccd_static_only = true; }},
      {"aabb-5mm", [](PhysicsConfig& c) { S8Defaults(c).aabb_margin = 0.005f; }},
      {"aabb-10mm", [](PhysicsConfig& c) { S8Defaults(c).aabb_margin = 0.01f; }},
      {"aabb-hyst-1cm", [](PhysicsConfig& c) {
         S8Defaults(c).aabb_margin = 0.005f;
         c.aabb_hysteresis = 0.01f;
       }},
      {"aabb-hyst-2cm", [](PhysicsConfig& c) {
         S8Defaults(c).aabb_margin = 0.005f;
         c.aabb_hysteresis = 0.02f;
       }},
      {"islands-off-aabb-5mm", [](PhysicsConfig& c) {
         S8Defaults(c).split_islands = false;
         c.aabb_margin = 0.005f;
       }},
      // The session-11 pick: every setting above that passed and saved something, together.
      {"s11-combo", [](PhysicsConfig& c) {
         TwoCachedFrictionDirs(S8Defaults(c)).solver_iterations = 4;
         c.split_islands = false;
         c.aabb_margin = 0.005f;
       }},
      // Patch friction (physics/contact_solver.h), two tangent rows and a twist row
      // per manifold instead of friction rows per contact point.
      {"patch", [](PhysicsConfig& c) { S8Defaults(c).patch_friction = true; }},
      {"patch-iter5", [](PhysicsConfig& c) {
         S8Defaults(c).patch_friction = true;
         c.solver_iterations = 5;
       }},
      {"patch-iter4", [](PhysicsConfig& c) {
         S8Defaults(c).patch_friction = true;
         c.solver_iterations = 4;
       }},
      {"patch-iter3", [](PhysicsConfig& c) {
         S8Defaults(c).patch_friction = true;
         c.solver_iterations = 3;
       }},
      // Patch friction with one solver batch and 5 mm AABB margin.
      {"s12-combo", [](PhysicsConfig& c) {
         S8Defaults(c).patch_friction = true;
         c.solver_iterations = 4;
         c.split_islands = false;
         c.aabb_margin = 0.005f;
       }},
      {"s12-combo-iter5", [](PhysicsConfig& c) {
         S8Defaults(c).patch_friction = true;
         c.solver_iterations = 5;
         c.split_islands = false;
         c.aabb_margin = 0.005f;
       }},
      {"contact-proc-5mm", [](PhysicsConfig& c) {
         S8Defaults(c).contact_processing_threshold = 0.005f;
       }},
      // Why 30 Hz fails the suite: one suspect changed each (compare per simulated second).
      {"rate-30hz-split", [](PhysicsConfig& c) {
         S8Defaults(c).fixed_dt = 1.0f / 30.0f;
         c.split_impulse = true;
       }},
      {"rate-30hz-2dir", [](PhysicsConfig& c) {
         S8Defaults(c).fixed_dt = 1.0f / 30.0f;
         c.two_friction_directions = true;
         c.friction_direction_caching = true;
         c.velocity_dependent_friction = false;
       }},
      {"rate-30hz-iter10", [](PhysicsConfig& c) {
         S8Defaults(c).fixed_dt = 1.0f / 30.0f;
         c.solver_iterations = 10;
       }},
      {"s8-rate-30hz", [](PhysicsConfig& c) { S8Defaults(c).fixed_dt = 1.0f / 30.0f; }},
      {"s8-rate-40hz", [](PhysicsConfig& c) { S8Defaults(c).fixed_dt = 1.0f / 40.0f; }},
  };
}

}  // namespace edgephys::physics
