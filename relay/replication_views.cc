// ClientReplicator's per-entity views and acknowledgements (relay/replication.h): the views by
// entity slot, forgetting despawned entities, and routing a packet's acknowledgement to the
// soft-body sender or the state stream.
#include "relay/entity.h"
#include "relay/replication.h"

namespace edgephys {

void ClientReplicator::OnPacketAcked(uint16_t sequence) {
  if (soft_->OnAcked(sequence)) return;
  stream_->OnAcked(sequence);
}

void ClientReplicator::Forget(uint32_t entity_id) {
  soft_views_.erase(entity_id);
  soft_->Forget(entity_id);
  stream_->Forget(entity_id);
  if (const uint32_t* slot = view_slot_of_.Find(entity_id); slot != nullptr) {
    ResetView(*slot);
    view_slot_of_.Erase(entity_id);
    --live_views_;
  }
}

ClientReplicator::View& ClientReplicator::ViewOf(const Entity& e) {
  if (e.slot >= views_.size()) views_.resize(e.slot + 1);
  View& v = views_[e.slot];
  if (v.serial == e.serial) return v;
  if (v.serial != 0) {  // the slot's previous occupant (not forgotten)
    if (const uint32_t* s = view_slot_of_.Find(v.id); s != nullptr && *s == e.slot) {
      view_slot_of_.Erase(v.id);
    }
    --live_views_;
  }
  if (const uint32_t* old = view_slot_of_.Find(e.id); old != nullptr && *old != e.slot) {
    ResetView(*old);  // the id's previous entity, in another slot
    --live_views_;
  }
  ResetView(e.slot);
  v.serial = e.serial;
  v.id = e.id;
  *view_slot_of_.TryEmplace(e.id).first = e.slot;
  ++live_views_;
  return v;
}

void ClientReplicator::ResetView(uint32_t slot) { views_[slot] = View{}; }

size_t ClientReplicator::tracked_entities() const {
  return std::max(live_views_, soft_views_.size());
}

}  // namespace edgephys
