// Internal to physics/: the Bullet world, solver and solver settings a PhysicsConfig asks for
// (PhysicsWorld's constructor). Split out so that the settings measured on the full stir
// (bench/physics_cost_report.cc) live in one place.
//
// Thread-safety: none; everything returned is owned and used by one PhysicsWorld.
// Ownership: the caller owns what is returned; the world does not own the dispatcher,
//   broadphase, solver or collision configuration passed in (they must outlive it).
#pragma once

#include <memory>

#include "physics_backend/physics_world.h"

class btBroadphaseInterface;
class btCollisionConfiguration;
class btCollisionDispatcher;
class btConstraintSolver;
class btDiscreteDynamicsWorld;
class btSoftBodyWorldInfo;

namespace edgephys::physics::internal {

// config.solver: btSequentialImpulseConstraintSolver or btNNCGConstraintSolver.
std::unique_ptr<btConstraintSolver> NewSolver(const PhysicsConfig& config);

// btSoftRigidDynamicsWorld (config.soft_body_world; *soft_info then points at its world info,
// otherwise it is set to nullptr) or btDiscreteDynamicsWorld. With config.ccd_static_only the
// world's CCD sweeps (predictive contacts and motion clamping) see only static and kinematic
// bodies: around those two passes of every step, each dynamic CCD body's broadphase mask is
// narrowed to btBroadphaseProxy::StaticFilter and restored afterwards (O(dynamic bodies) per
// step; the broadphase never sees the narrowed masks, which only the sweeps read).
std::unique_ptr<btDiscreteDynamicsWorld> NewBulletWorld(const PhysicsConfig& config,
                                                        btCollisionDispatcher* dispatcher,
                                                        btBroadphaseInterface* broadphase,
                                                        btConstraintSolver* solver,
                                                        btCollisionConfiguration* collision_config,
                                                        btSoftBodyWorldInfo** soft_info);

// Gravity, solver iterations and modes, islands, AABB and CCD restitution settings from config.
void ApplyWorldSettings(const PhysicsConfig& config, btDiscreteDynamicsWorld* world);

}  // namespace edgephys::physics::internal
