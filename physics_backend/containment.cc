#include "physics_backend/containment.h"

#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace edgephys::physics {
namespace {

// Bullet's broadphase pairing rule (btOverlappingPairCache::needsBroadphaseCollision) plus the
// bodies' own ignore lists: would Bullet ever make a contact between `a` and `b`?
bool Collide(const btRigidBody* a, const btRigidBody* b) {
  const btBroadphaseProxy* pa = a->getBroadphaseHandle();
  const btBroadphaseProxy* pb = b->getBroadphaseHandle();
  if (pa == nullptr || pb == nullptr) return false;
  if ((pa->m_collisionFilterGroup & pb->m_collisionFilterMask) == 0) return false;
  if ((pb->m_collisionFilterGroup & pa->m_collisionFilterMask) == 0) return false;
  return a->checkCollideWith(b);
}

}  // namespace

Containment::Containment(float fraction) : fraction_(std::clamp(fraction, 0.0f, 1.0f)) {}

void Containment::OnAdd(btRigidBody* body) {
  const btCollisionShape* shape = body->getCollisionShape();
  if (shape == nullptr) return;
  if (!body->isStaticOrKinematicObject()) {
    btVector3 center;
    btScalar radius;
    shape->getBoundingSphere(center, radius);
    max_radius_ = std::max(max_radius_, radius + center.length());
    return;
  }
  if (body->isKinematicObject() || !body->hasContactResponse() ||
      shape->getShapeType() != BOX_SHAPE_PROXYTYPE) {
    return;
  }
  const auto* box = static_cast<const btBoxShape*>(shape);
  walls_.push_back(Wall{body, box->getHalfExtentsWithMargin(), btVector3(), btVector3()});
}

void Containment::OnRemove(btRigidBody* body) {
  std::erase_if(walls_, [body](const Wall& w) { return w.body == body; });
}

void Containment::Before(const btAlignedObjectArray<btRigidBody*>& bodies) {
  if (walls_.empty()) return;
  before_.resize(static_cast<size_t>(bodies.size()));
  for (int i = 0; i < bodies.size(); ++i) before_[i] = bodies[i]->getWorldTransform().getOrigin();
}

void Containment::After(const btAlignedObjectArray<btRigidBody*>& bodies) {
  if (walls_.empty()) return;
  const btVector3 grow(max_radius_, max_radius_, max_radius_);
  for (Wall& w : walls_) {
    const btTransform& t = w.body->getWorldTransform();
    const btVector3 ext = t.getBasis().absolute() * w.half;
    w.mn = t.getOrigin() - ext - grow;
    w.mx = t.getOrigin() + ext + grow;
  }
  for (int i = 0; i < bodies.size(); ++i) {
    btRigidBody* b = bodies[i];
    if (b->isStaticOrKinematicObject() || !b->isActive() || !b->hasContactResponse()) continue;
    for (const Wall& w : walls_) {
      if (Contain(b, w, before_[i])) ++projections_;
    }
  }
}

bool Containment::Contain(btRigidBody* body, const Wall& wall, const btVector3& before) {
  const btVector3 after = body->getWorldTransform().getOrigin();
  // The path's bounds against the wall's, grown by the largest body: most pairs end here.
  btVector3 pmn = before, pmx = before;
  pmn.setMin(after);
  pmx.setMax(after);
  if (pmx.x() < wall.mn.x() || pmn.x() > wall.mx.x() || pmx.y() < wall.mn.y() ||
      pmn.y() > wall.mx.y() || pmx.z() < wall.mn.z() || pmn.z() > wall.mx.z()) {
    return false;
  }
  if (!Collide(body, wall.body)) return false;
  // In the wall's frame: its box is [-h, h]; the body's centre may be anywhere in (lo, hi)
  // for the two to overlap, where its extents along the wall's axes are [emn, emx].
  const btTransform& tw = wall.body->getWorldTransform();
  const btVector3 c0 = tw.invXform(before);
  const btVector3 c1 = tw.invXform(after);
  const btVector3& h = wall.half;
  if (std::abs(c0.x()) < h.x() && std::abs(c0.y()) < h.y() && std::abs(c0.z()) < h.z()) {
    return false;  // the centre started inside the box: not covered
  }
  btVector3 emn, emx;
  const btTransform rel(tw.getBasis().transposeTimes(body->getWorldTransform().getBasis()));
  body->getCollisionShape()->getAabb(rel, emn, emx);
  const btVector3 lo = -h - emx, hi = h - emn;
  bool clear = false;  // separated from the box at the start of the step
  for (int k = 0; k < 3; ++k) clear = clear || c0[k] <= lo[k] || c0[k] >= hi[k];
  int axis = -1;
  btScalar side = 0;   // +1: the face at +h[axis], -1: the one at -h[axis]
  btScalar limit = 0;  // the deepest the body may end (m)
  if (clear) {
    // Where the centre's path enters the grown box (slab test); a path that misses it, or ends
    // before it, is no concern of ours.
    btScalar t_in = -std::numeric_limits<btScalar>::infinity();
    btScalar t_out = std::numeric_limits<btScalar>::infinity();
    for (int k = 0; k < 3; ++k) {
      const btScalar d = c1[k] - c0[k];
      if (std::abs(d) < btScalar(1e-12)) {
        if (c0[k] <= lo[k] || c0[k] >= hi[k]) return false;
        continue;
      }
      btScalar ta = (lo[k] - c0[k]) / d, tb = (hi[k] - c0[k]) / d;
      if (ta > tb) std::swap(ta, tb);
      if (ta > t_in) t_in = ta, axis = k, side = d < 0 ? btScalar(1) : btScalar(-1);
      t_out = std::min(t_out, tb);
    }
    if (axis < 0 || t_in > t_out || t_in > 1 || t_in < 0) return false;
  } else {
    // Already touching: the face of least penetration at the start, and how deep it was.
    btScalar least = std::numeric_limits<btScalar>::infinity();
    for (int k = 0; k < 3; ++k) {
      if (hi[k] - c0[k] < least) least = hi[k] - c0[k], axis = k, side = 1;
      if (c0[k] - lo[k] < least) least = c0[k] - lo[k], axis = k, side = -1;
    }
    const btScalar extent = side > 0 ? -emn[axis] : emx[axis];
    limit = std::max(least, fraction_ * extent);
  }
  const btScalar depth = side > 0 ? hi[axis] - c1[axis] : c1[axis] - lo[axis];
  const btScalar extent = side > 0 ? -emn[axis] : emx[axis];
  if (clear ? depth <= fraction_ * extent : depth <= limit) return false;
  btVector3 fixed = c1;
  fixed[axis] = side > 0 ? hi[axis] - limit : lo[axis] + limit;
  btTransform moved = body->getWorldTransform();
  moved.setOrigin(tw * fixed);
  const btVector3 normal = tw.getBasis().getColumn(axis) * side;  // out of the wall
  btVector3 v = body->getLinearVelocity();
  const btScalar vn = v.dot(normal);
  if (vn < 0) {
    const btScalar e = clear ? body->getRestitution() * wall.body->getRestitution() : 0;
    v -= normal * (vn * (1 + e));
    body->setLinearVelocity(v);
  }
  body->setCenterOfMassTransform(moved);  // also the interpolation transform motion states read
  return true;
}

}  // namespace edgephys::physics
