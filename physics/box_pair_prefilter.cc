// Box-pair prefilter near callback (see box_pair_prefilter.h).
#include "physics/box_pair_prefilter.h"

namespace edgephys::physics::internal {
namespace {

// Bounding radius of a box about its centre, as btBoxBoxDetector sees it (half extents with
// the collision margin).
btScalar BoxRadius(const btCollisionShape* shape) {
  return static_cast<const btBoxShape*>(shape)->getHalfExtentsWithMargin().length();
}

}  // namespace

void BoxPairPrefilterNearCallback(btBroadphasePair& pair, btCollisionDispatcher& dispatcher,
                                  const btDispatcherInfo& info) {
  auto* o0 = static_cast<btCollisionObject*>(pair.m_pProxy0->m_clientObject);
  auto* o1 = static_cast<btCollisionObject*>(pair.m_pProxy1->m_clientObject);
  const btCollisionShape* s0 = o0->getCollisionShape();
  const btCollisionShape* s1 = o1->getCollisionShape();
  if (pair.m_algorithm == nullptr || s0->getShapeType() != BOX_SHAPE_PROXYTYPE ||
      s1->getShapeType() != BOX_SHAPE_PROXYTYPE ||
      info.m_dispatchFunc != btDispatcherInfo::DISPATCH_DISCRETE) {
    btCollisionDispatcher::defaultNearCallback(pair, dispatcher, info);
    return;
  }
  const btScalar reach = BoxRadius(s0) + BoxRadius(s1) + kBoxPrefilterSlack;
  const btVector3 d = o1->getWorldTransform().getOrigin() - o0->getWorldTransform().getOrigin();
  // Written so that NaN fails the test (and takes Bullet's path).
  if (!(d.length2() > reach * reach)) {
    btCollisionDispatcher::defaultNearCallback(pair, dispatcher, info);
    return;
  }
  // Bullet's path would stop here too (no algorithm call at all).
  if (!dispatcher.needsCollision(o0, o1)) return;
  // What btBoxBoxCollisionAlgorithm::processCollision does when the detector reports nothing:
  // btManifoldResult::refreshContactPoints on its own manifold (if it has points).
  thread_local btManifoldArray manifolds;
  manifolds.resize(0);
  pair.m_algorithm->getAllContactManifolds(manifolds);
  for (int i = 0; i < manifolds.size(); ++i) {
    btPersistentManifold* m = manifolds[i];
    if (m->getNumContacts() == 0) continue;
    m->refreshContactPoints(m->getBody0()->getWorldTransform(), m->getBody1()->getWorldTransform());
  }
}

}  // namespace edgephys::physics::internal
