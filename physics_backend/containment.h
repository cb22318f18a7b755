// Containment: the analytic guarantee that keeps dynamic bodies out of static boxes (walls,
// floors, ceilings, any static box of any orientation), without CCD sweeps
// (PhysicsConfig::containment).
//
// The rule, per Bullet step, for every active dynamic body that responds to contacts and every
// static box it can collide with (collision filters; Bullet's own pairing rule): let d be how
// deep the body's support reaches past the box face it came from (m, along that face's normal;
// the face is the one its centre's path entered through if it was clear of the box at the start
// of the step, else the face of least penetration at the start), and e its extent along that
// normal. If d exceeds max(fraction * e, d at the start of the step), the body is moved back
// along the normal: to touching (d = 0) if it was clear at the start (a body too fast for its
// discrete contact, i.e. what CCD would catch), else to that limit (a body squeezed deeper by
// what presses on it). Its velocity into the face is removed, and for a body that was clear,
// reflected with the combined restitution (the product, as Bullet's). Each move counts
// (projections(), PhysicsCounters::contained).
// Not covered (Bullet's contacts or CCD sweeps still handle them): a body whose centre is inside
// a box at the start of a step (spawned or teleported there); static colliders that are not a
// single box at the body origin (spheres, meshes, compounds); kinematic and dynamic obstacles
// (hands, the stirrer, other bodies); bodies that are not rigid (soft bodies).
// A box that is not part of any room is covered just the same: a body outside a room stays
// outside it, and a body that flies over a wall (above it) is not touched.
//
// Accuracy: a body within the limit is untouched (Bullet's contacts resolve it as without
// containment), so resting and sliding contacts are bit-identical; a projected body loses the
// part of the step's motion that went into the box, as motion clamping does.
// Cost: O(walls) per step to refresh the walls' bounds, O(active dynamic bodies x walls) for a
// bounds test of each body's step path against each wall grown by the largest dynamic body's
// bounding radius, and an exact test (one virtual getAabb, a transform) for the pairs that
// pass it (in the full stir: the boxes near a wall or on the floor). No broadphase queries, no
// allocation once the walls and bodies are known.
// Thread-safety: none; owned by one PhysicsWorld, called from its Bullet world's step.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include <LinearMath/btAlignedObjectArray.h>
#include <LinearMath/btVector3.h>

class btCollisionObject;
class btRigidBody;

namespace edgephys::physics {

class Containment {
 public:
  // `fraction`: the share of a body's extent along a face normal it may reach into a static
  // box before it is projected (PhysicsConfig::containment_depth_fraction, clamped to [0, 1]).
  explicit Containment(float fraction);

  // Called for every rigid body the Bullet world adds or removes; keeps the static boxes (and
  // the largest dynamic bounding radius). O(1) add, O(walls) remove.
  void OnAdd(btRigidBody* body);
  void OnRemove(btRigidBody* body);

  // Around one Bullet step (TunedWorld): Before, at its start, records the centres of `bodies`
  // (the world's non-static rigid bodies); After, right after its integration, applies the rule
  // above to the active dynamic ones. The array must not change in between.
  void Before(const btAlignedObjectArray<btRigidBody*>& bodies);
  void After(const btAlignedObjectArray<btRigidBody*>& bodies);

  uint64_t projections() const { return projections_; }
  size_t walls() const { return walls_.size(); }

 private:
  struct Wall {
    const btRigidBody* body;
    btVector3 half;     // the box's half extents (with margin: the box Bullet collides with)
    btVector3 mn, mx;   // world bounds, refreshed each step, grown by max_radius_
  };
  // Applies the rule to one body against one wall; true if the body was moved.
  bool Contain(btRigidBody* body, const Wall& wall, const btVector3& before);

  float fraction_;
  btScalar max_radius_ = 0;
  std::vector<Wall> walls_;
  std::vector<btVector3> before_;
  uint64_t projections_ = 0;
};

}  // namespace edgephys::physics
