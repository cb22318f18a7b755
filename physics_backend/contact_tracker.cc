// Contact and trigger tracking, run after every Step(): the touching pairs of this step are
// diffed against the previous step's into Collision/Trigger Enter and Exit events (sorted by
// pair, so deterministic). O(contact manifolds + pairs log pairs); the pair vectors are reused.
#include <algorithm>

#include "physics_backend/physics_world_internal.h"

namespace edgephys::physics {
namespace {

// Whether any contact point of `m` is within `touch` (m).
bool Touching(const btPersistentManifold& m, btScalar touch) {
  const int contacts = m.getNumContacts();
  for (int k = 0; k < contacts; ++k) {
    if (m.getContactPoint(k).getDistance() <= touch) return true;
  }
  return false;
}

}  // namespace

void PhysicsWorld::DiffContacts() {
  // This step's touching pairs: solid pairs as (smaller id, larger id), trigger pairs as
  // (trigger's entity, other entity). Trigger-trigger pairs and self-contacts are ignored.
  new_pairs_.clear();
  const int manifolds = dispatcher_->getNumManifolds();
  const btScalar touch = config_.contact_distance;
  for (int i = 0; i < manifolds; ++i) {
    const btPersistentManifold* m = dispatcher_->getManifoldByIndexInternal(i);
    if (!Touching(*m, touch)) continue;
    const btCollisionObject* o0 = m->getBody0();
    const btCollisionObject* o1 = m->getBody1();
    const auto* e0 = static_cast<const Entity*>(o0->getUserPointer());
    const auto* e1 = static_cast<const Entity*>(o1->getUserPointer());
    if (e0 == nullptr || e1 == nullptr || e0 == e1) continue;
    const bool t0 = !o0->hasContactResponse();
    const bool t1 = !o1->hasContactResponse();
    if (t0 && t1) continue;
    PairKey key;
    if (t0 || t1) {
      key.a = t0 ? e0->id : e1->id;
      key.b = t0 ? e1->id : e0->id;
      key.trigger = 1;
    } else {
      key.a = std::min(e0->id, e1->id);
      key.b = std::max(e0->id, e1->id);
    }
    new_pairs_.push_back(key);
  }
  std::sort(new_pairs_.begin(), new_pairs_.end());
  new_pairs_.erase(std::unique(new_pairs_.begin(), new_pairs_.end()), new_pairs_.end());

  // Merge-diff against the previous step's pairs: deterministic, sorted by pair.
  size_t i = 0, j = 0;
  const uint64_t step = stats_.steps;
  auto emit = [&](const PairKey& k, bool enter) {
    PhysicsEventType type;
    if (k.trigger) {
      type = enter ? PhysicsEventType::kTriggerEnter : PhysicsEventType::kTriggerExit;
    } else {
      type = enter ? PhysicsEventType::kCollisionEnter : PhysicsEventType::kCollisionExit;
    }
    PushEvent(PhysicsEvent{type, GuardCause::kNone, k.a, k.b, step});
  };
  while (i < pairs_.size() || j < new_pairs_.size()) {
    if (j == new_pairs_.size() || (i < pairs_.size() && pairs_[i] < new_pairs_[j])) {
      emit(pairs_[i++], false);
    } else if (i == pairs_.size() || new_pairs_[j] < pairs_[i]) {
      emit(new_pairs_[j++], true);
    } else {
      ++i, ++j;
    }
  }
  pairs_.swap(new_pairs_);
}

}  // namespace edgephys::physics
