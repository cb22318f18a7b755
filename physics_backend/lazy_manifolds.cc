// Box-box manifolds only for touching pairs (see lazy_manifolds.h for the rule and its effects).
#include "physics_backend/lazy_manifolds.h"

#include <BulletCollision/CollisionDispatch/btActivatingCollisionAlgorithm.h>
#include <BulletCollision/CollisionDispatch/btBoxBoxDetector.h>
#include <BulletCollision/CollisionDispatch/btCollisionObjectWrapper.h>

#include <algorithm>
#include <new>

namespace edgephys::physics {
namespace {

// Collects what btBoxBoxDetector reports while a pair has no manifold. The ODE box-box test
// reports at most 4 points; more are only counted (the caller then runs the detector again).
class PointCollector final : public btDiscreteCollisionDetectorInterface::Result {
 public:
  explicit PointCollector(btScalar threshold) : threshold_(threshold) {}
  void setShapeIdentifiersA(int, int) override {}
  void setShapeIdentifiersB(int, int) override {}
  void addContactPoint(const btVector3& normal_on_b, const btVector3& point, btScalar depth) override {
    // btManifoldResult::addContactPoint drops points beyond the manifold's breaking threshold.
    if (depth > threshold_) return;
    if (count_ < kMax) points_[count_] = Point{normal_on_b, point, depth};
    ++count_;
  }
  int count() const { return count_; }
  bool overflowed() const { return count_ > kMax; }
  void Replay(btManifoldResult* out) const {
    for (int i = 0; i < count_; ++i) out->addContactPoint(points_[i].normal, points_[i].point, points_[i].depth);
  }

 private:
  static constexpr int kMax = 8;
  struct Point {
    btVector3 normal;
    btVector3 point;
    btScalar depth;
  };
  btScalar threshold_;
  int count_ = 0;
  Point points_[kMax];
};

class LazyBoxBoxAlgorithm final : public btActivatingCollisionAlgorithm {
 public:
  LazyBoxBoxAlgorithm(const btCollisionAlgorithmConstructionInfo& ci,
                      const btCollisionObjectWrapper* body0, const btCollisionObjectWrapper* body1,
                      int keep_steps, bool relative_threshold, LazyManifoldStats* stats)
      : btActivatingCollisionAlgorithm(ci, body0, body1),
        object0_(body0->getCollisionObject()),
        object1_(body1->getCollisionObject()),
        keep_steps_(keep_steps),
        stats_(stats) {
    // The threshold btCollisionDispatcher::getNewManifold will give this pair's manifold.
    threshold_ = gContactBreakingThreshold;
    if (relative_threshold) {
      threshold_ = std::min(
          object0_->getCollisionShape()->getContactBreakingThreshold(gContactBreakingThreshold),
          object1_->getCollisionShape()->getContactBreakingThreshold(gContactBreakingThreshold));
    }
  }

  ~LazyBoxBoxAlgorithm() override {
    if (manifold_ != nullptr) m_dispatcher->releaseManifold(manifold_);
  }

  void processCollision(const btCollisionObjectWrapper* body0,
                        const btCollisionObjectWrapper* body1, const btDispatcherInfo& info,
                        btManifoldResult* out) override {
    const auto* box0 = static_cast<const btBoxShape*>(body0->getCollisionShape());
    const auto* box1 = static_cast<const btBoxShape*>(body1->getCollisionShape());
    btDiscreteCollisionDetectorInterface::ClosestPointInput input;
    input.m_maximumDistanceSquared = BT_LARGE_FLOAT;
    input.m_transformA = body0->getWorldTransform();
    input.m_transformB = body1->getWorldTransform();
    btBoxBoxDetector detector(box0, box1);
    if (manifold_ == nullptr) {
      PointCollector found(threshold_);
      detector.getClosestPoints(input, found, info.m_debugDraw);
      if (found.count() == 0) return;  // apart: no manifold memory touched
      manifold_ = m_dispatcher->getNewManifold(object0_, object1_);
      ++stats_->created;
      empty_steps_ = 0;
      out->setPersistentManifold(manifold_);
      if (found.overflowed()) {
        detector.getClosestPoints(input, *out, info.m_debugDraw);
      } else {
        found.Replay(out);
      }
    } else {
      // Bullet's btBoxBoxCollisionAlgorithm::processCollision with persistent contacts.
      out->setPersistentManifold(manifold_);
      detector.getClosestPoints(input, *out, info.m_debugDraw);
    }
    out->refreshContactPoints();
    if (manifold_->getNumContacts() > 0) {
      empty_steps_ = 0;
      return;
    }
    if (++empty_steps_ <= keep_steps_) return;
    m_dispatcher->releaseManifold(manifold_);
    out->setPersistentManifold(nullptr);
    manifold_ = nullptr;
    empty_steps_ = 0;
    ++stats_->released;
  }

  btScalar calculateTimeOfImpact(btCollisionObject*, btCollisionObject*, const btDispatcherInfo&,
                                 btManifoldResult*) override {
    return 1;  // as Bullet's box-box algorithm: no time of impact
  }

  void getAllContactManifolds(btManifoldArray& manifolds) override {
    if (manifold_ != nullptr) manifolds.push_back(manifold_);
  }

 private:
  const btCollisionObject* object0_;  // the manifold's bodies, in Bullet's constructor's order
  const btCollisionObject* object1_;
  int keep_steps_;
  LazyManifoldStats* stats_;
  btScalar threshold_ = 0;
  btPersistentManifold* manifold_ = nullptr;  // owned (from the dispatcher) while it exists
  int empty_steps_ = 0;                        // consecutive processed steps without a point
};

}  // namespace

btCollisionAlgorithm* LazyBoxBoxCreateFunc::CreateCollisionAlgorithm(
    btCollisionAlgorithmConstructionInfo& ci, const btCollisionObjectWrapper* body0,
    const btCollisionObjectWrapper* body1) {
  void* mem = ci.m_dispatcher1->allocateCollisionAlgorithm(sizeof(LazyBoxBoxAlgorithm));
  return new (mem)
      LazyBoxBoxAlgorithm(ci, body0, body1, keep_steps_, relative_threshold_, &stats_);
}

}  // namespace edgephys::physics
