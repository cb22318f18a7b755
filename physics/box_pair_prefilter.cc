// Box-pair prefilter near callback (see box_pair_prefilter.h).
#include "physics/box_pair_prefilter.h"

namespace edgephys::physics::internal {
namespace {

// Half extents of a box as btBoxBoxDetector sees it (with the collision margin; by value, as
// Bullet returns them).
btVector3 HalfExtents(const btCollisionObject& o) {
  return static_cast<const btBoxShape*>(o.getCollisionShape())->getHalfExtentsWithMargin();
}

// Whether the sphere (centre c, radius r) lies farther than r from box `box`, i.e. misses it.
bool SphereMissesBox(const btCollisionObject& box, const btVector3& c, btScalar r) {
  const btVector3 local = box.getWorldTransform().invXform(c);
  const btVector3 h = HalfExtents(box);
  btScalar d2 = 0;
  for (int i = 0; i < 3; ++i) {
    const btScalar excess = btFabs(local[i]) - h[i];
    if (excess > 0) d2 += excess * excess;
  }
  return d2 > r * r;  // NaN: false
}

}  // namespace

bool BoxesCannotTouch(const btCollisionObject& a, const btCollisionObject& b) {
  const btVector3 ha = HalfExtents(a);
  const btVector3 hb = HalfExtents(b);
  const btScalar ra = ha.length() + kBoxPrefilterSlack;
  const btScalar rb = hb.length() + kBoxPrefilterSlack;
  const btVector3& ca = a.getWorldTransform().getOrigin();
  const btVector3& cb = b.getWorldTransform().getOrigin();
  const btScalar d2 = (cb - ca).length2();
  if (d2 > (ra + rb) * (ra + rb)) return true;  // bounding spheres apart
  // Inscribed spheres overlap: the boxes overlap, Bullet's test will report contacts.
  const btScalar ia = btMin(btMin(ha.x(), ha.y()), ha.z());  // inscribed radii
  const btScalar ib = btMin(btMin(hb.x(), hb.y()), hb.z());
  if (!(d2 >= (ia + ib) * (ia + ib))) return false;  // also NaN
  // Each box's bounding sphere against the other box.
  return SphereMissesBox(a, cb, rb) || SphereMissesBox(b, ca, ra);
}

void BoxPairPrefilterNearCallback(btBroadphasePair& pair, btCollisionDispatcher& dispatcher,
                                  const btDispatcherInfo& info) {
  auto* o0 = static_cast<btCollisionObject*>(pair.m_pProxy0->m_clientObject);
  auto* o1 = static_cast<btCollisionObject*>(pair.m_pProxy1->m_clientObject);
  if (pair.m_algorithm == nullptr ||
      o0->getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE ||
      o1->getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE ||
      info.m_dispatchFunc != btDispatcherInfo::DISPATCH_DISCRETE || !BoxesCannotTouch(*o0, *o1)) {
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
