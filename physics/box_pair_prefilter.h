// The box-pair prefilter: a near callback (btCollisionDispatcher::setNearCallback) that skips
// Bullet's box-box narrowphase for pairs whose bounding spheres are apart.
//
// Why: a box's broadphase AABB is up to sqrt(3) times wider than the box when it is rotated, so
// in a dense pile a good share of the pairs the broadphase hands the narrowphase are boxes that
// cannot touch. Bullet runs its full box-box test (btBoxBoxDetector, a 15-axis separating axis
// test) on each of them every step.
//
// What: for a pair of two btBoxShape objects whose collision algorithm already exists, if the
// distance between the centres exceeds the sum of the boxes' bounding radii (half extents with
// margin) by more than kSlack, the boxes are disjoint, so btBoxBoxDetector would report nothing.
// The callback then does exactly what Bullet's btBoxBoxCollisionAlgorithm does when nothing is
// reported: it refreshes the pair's manifold (drops points that no longer hold). Every other
// pair, and every pair Bullet would not collide (btCollisionDispatcher::needsCollision), goes to
// btCollisionDispatcher::defaultNearCallback unchanged. Trajectories and contact events are
// therefore bit-identical to Bullet's own callback (test: box_pair_prefilter_test.cc).
//
// Precondition: box-box pairs use Bullet's btBoxBoxCollisionAlgorithm (the dispatcher's
// default); PhysicsWorld does not install the callback when manifold reuse replaces it.
// Cost: one distance test per box pair and step (a few ns); a skipped pair saves the box-box
// test and the manifold result (~100-200 ns). Threading: none beyond the dispatcher's (the
// callback is stateless; it keeps one thread_local scratch array). Failure: none; a non-finite
// transform fails the test and goes to Bullet's path.
#pragma once

#include <btBulletCollisionCommon.h>

namespace edgephys::physics::internal {

// Margin (m) on top of the bounding radii before a pair is skipped; far above float rounding
// of the centre distance at room scale, so the skip never hides a contact.
inline constexpr btScalar kBoxPrefilterSlack = btScalar(1e-3);

// btNearCallback: see the header comment.
void BoxPairPrefilterNearCallback(btBroadphasePair& pair, btCollisionDispatcher& dispatcher,
                                  const btDispatcherInfo& info);

}  // namespace edgephys::physics::internal
