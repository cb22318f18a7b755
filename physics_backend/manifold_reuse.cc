// Contact manifold reuse for box-box pairs (see manifold_reuse.h for the rule and its bounds).
#include "physics_backend/manifold_reuse.h"

#include <BulletCollision/CollisionDispatch/btBoxBoxCollisionAlgorithm.h>

#include <algorithm>
#include <cmath>
#include <new>

namespace edgephys::physics {
namespace {

class ReusingBoxBoxAlgorithm final : public btBoxBoxCollisionAlgorithm {
 public:
  ReusingBoxBoxAlgorithm(const btCollisionAlgorithmConstructionInfo& ci,
                         const btCollisionObjectWrapper* body0,
                         const btCollisionObjectWrapper* body1, btScalar distance,
                         ManifoldReuseStats* stats)
      : btBoxBoxCollisionAlgorithm(nullptr, ci, body0, body1), distance_(distance), stats_(stats) {
    btVector3 center;
    body1->getCollisionShape()->getBoundingSphere(center, radius1_);
    radius1_ += center.length();
  }

  void processCollision(const btCollisionObjectWrapper* body0,
                        const btCollisionObjectWrapper* body1, const btDispatcherInfo& info,
                        btManifoldResult* out) override {
    const btTransform& t0 = body0->getWorldTransform();
    const btTransform& t1 = body1->getWorldTransform();
    // Body 1 in body 0's frame.
    const btVector3 rel_origin = t0.invXform(t1.getOrigin());
    const btMatrix3x3 rel_basis = t0.getBasis().transposeTimes(t1.getBasis());
    if (manifold_ != nullptr && WithinDistance(rel_origin, rel_basis)) {
      TurnNormals();
      out->setPersistentManifold(manifold_);
      out->refreshContactPoints();
      ++stats_->reused;
      return;
    }
    btBoxBoxCollisionAlgorithm::processCollision(body0, body1, info, out);
    manifold_ = out->getPersistentManifold();
    ref_origin_ = rel_origin;
    ref_basis_ = rel_basis;
    if (manifold_ != nullptr) last_basis1_ = manifold_->getBody1()->getWorldTransform().getBasis();
    ++stats_->full;
  }

 private:
  // Whether any point of body 1 moved at most distance_ relative to body 0 since the recorded
  // pose: origin translation plus rotation angle times body 1's bounding radius.
  bool WithinDistance(const btVector3& rel_origin, const btMatrix3x3& rel_basis) const {
    const btScalar moved = (rel_origin - ref_origin_).length();
    if (moved > distance_) return false;
    const btMatrix3x3 d = ref_basis_.transposeTimes(rel_basis);  // rotation since recorded
    const btScalar trace = d[0][0] + d[1][1] + d[2][2];
    if (trace < btScalar(1)) return false;  // more than 90 degrees
    const btVector3 axis(d[2][1] - d[1][2], d[0][2] - d[2][0], d[1][0] - d[0][1]);
    const btScalar sine = std::min(btScalar(1), btScalar(0.5) * axis.length());
    return moved + std::asin(sine) * radius1_ <= distance_;
  }

  // A face normal is fixed to its box: turn the kept world normals with body 1's rotation since
  // the last step (the manifold's normal is on its body 1, which is this pair's body 1).
  void TurnNormals() {
    const btMatrix3x3& now = manifold_->getBody1()->getWorldTransform().getBasis();
    const btMatrix3x3 turn = now.timesTranspose(last_basis1_);
    last_basis1_ = now;
    for (int i = 0; i < manifold_->getNumContacts(); ++i) {
      btManifoldPoint& p = manifold_->getContactPoint(i);
      p.m_normalWorldOnB = turn * p.m_normalWorldOnB;
    }
  }

  btScalar distance_;
  ManifoldReuseStats* stats_;
  btScalar radius1_ = 0;
  btPersistentManifold* manifold_ = nullptr;  // owned by the base class; set by the first run
  btVector3 ref_origin_{0, 0, 0};
  btMatrix3x3 ref_basis_ = btMatrix3x3::getIdentity();
  btMatrix3x3 last_basis1_ = btMatrix3x3::getIdentity();
};

}  // namespace

btCollisionAlgorithm* ManifoldReuseCreateFunc::CreateCollisionAlgorithm(
    btCollisionAlgorithmConstructionInfo& ci, const btCollisionObjectWrapper* body0,
    const btCollisionObjectWrapper* body1) {
  void* mem = ci.m_dispatcher1->allocateCollisionAlgorithm(sizeof(ReusingBoxBoxAlgorithm));
  return new (mem) ReusingBoxBoxAlgorithm(ci, body0, body1, distance_, &stats_);
}

}  // namespace edgephys::physics
