// The box-pair prefilter: a near callback (btCollisionDispatcher::setNearCallback) that skips
// Bullet's box-box narrowphase for pairs of boxes that certainly do not touch.
//
// Why: a box's broadphase AABB is up to sqrt(3) times wider than the box when it is rotated, so
// in a dense pile a good share of the pairs the broadphase hands the narrowphase are boxes that
// cannot touch. Bullet runs its full box-box test (btBoxBoxDetector, a 15-axis separating axis
// test) on each of them every step.
//
// What: for a pair of two btBoxShape objects whose collision algorithm already exists, if the
// boxes are certainly disjoint (BoxesCannotTouch: bounding spheres apart, or one box's bounding
// sphere misses the other box, with kBoxPrefilterSlack to spare), btBoxBoxDetector would report
// nothing. The callback then does exactly what Bullet's btBoxBoxCollisionAlgorithm does when
// nothing is reported: it refreshes the pair's manifold (drops points that no longer hold).
// Every other pair, and every pair Bullet would not collide (needsCollision), goes to
// btCollisionDispatcher::defaultNearCallback unchanged. Trajectories and contact events are
// therefore bit-identical to Bullet's own callback (test: box_pair_prefilter_test.cc).
//
// Precondition: box-box pairs use Bullet's btBoxBoxCollisionAlgorithm (the dispatcher's
// default); PhysicsWorld does not install the callback when manifold reuse replaces it.
// Cost: one centre distance per box pair and step, plus two point-to-box distances when that
// does not decide (a few ns); a skipped pair saves the box-box test and the manifold result.
// Threading: none beyond the dispatcher's (the callback keeps one thread_local scratch array).
// Failure: none; a non-finite pose fails the tests and takes Bullet's path.

#pragma once

#include <btBulletCollisionCommon.h>

namespace edgephys::physics::internal {

// Margin (m) on top of the bounding radii before a pair is skipped; far above float rounding
// of the centre distance at room scale, so the skip never hides a contact.
inline constexpr btScalar kBoxPrefilterSlack = btScalar(1e-3);

// Whether two boxes (btBoxShape objects, centred on their origins) are certainly disjoint: their
// bounding spheres (radius grown by kBoxPrefilterSlack) are apart, or one box's bounding sphere
// misses the other box. False when unsure (inscribed spheres overlap, non-finite poses).
bool BoxesCannotTouch(const btCollisionObject& a, const btCollisionObject& b);

// btNearCallback: see the header comment.
void BoxPairPrefilterNearCallback(btBroadphasePair& pair, btCollisionDispatcher& dispatcher,
                                  const btDispatcherInfo& info);

}  // namespace edgephys::physics::internal
