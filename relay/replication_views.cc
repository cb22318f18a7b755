// ClientReplicator's per-entity views and acknowledgements (relay/replication.h): the views by
// entity slot, forgetting despawned entities, and routing a packet's acknowledgement to the
// soft-body sender, the lockstep member (relay/lockstep.h) or the state encoder.
#include "relay/entity.h"
#include "relay/lockstep.h"
#include "relay/replication.h"

namespace edgephys {

void ClientReplicator::OnPacketAcked(uint16_t sequence) {
  if (soft_ != nullptr && soft_->OnAcked(sequence)) return;
  SoftRecord* r_or_null =
      soft_records_.empty() ? nullptr : &soft_records_[sequence % soft_records_.size()];
  if (r_or_null != nullptr && r_or_null->valid && r_or_null->sequence == sequence) {
    SoftRecord& r = *r_or_null;
    r.valid = false;
    auto it = soft_views_.find(r.id);
    if (it != soft_views_.end() && it->second.sent_version == r.version) {
      SoftView& v = it->second;
      v.acked_chunks |= uint64_t{1} << r.chunk;
      if (v.chunk_count > 0 && v.acked_chunks == (v.chunk_count >= 64 ? ~uint64_t{0}
                                                                        : (uint64_t{1} << v.chunk_count) - 1)) {
        v.acked_version = r.version;
      }
    }
    return;
  }
  // In lockstep, its packets stand for canonical payloads (its own stream is set aside); out
  // of it, the stream adopted from the canonical one maps the sequences still in flight.
  if (member_ != nullptr && member_->in) {
    (void)member_->OnAcked(sequence);  // unknown or stale sequences: ignored
    return;
  }
  if (delta_ != nullptr) {
    delta_->OnPacketAcked(sequence);
  } else if (shared_ != nullptr) {
    shared_->OnPacketAcked(sequence);
  } else {
    tracker_.OnAcked(sequence);
  }
}

void ClientReplicator::Forget(uint32_t entity_id) {
  tracker_.Forget(entity_id);
  soft_views_.erase(entity_id);
  if (soft_ != nullptr) soft_->Forget(entity_id);
  if (delta_ != nullptr) delta_->Forget(entity_id);
  if (shared_ != nullptr) shared_->Forget(entity_id);
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

void ClientReplicator::ResetView(uint32_t slot) {
  views_[slot] = View{};
  if (UsesViewExtras()) {
    if (view_extras_.size() < views_.size()) view_extras_.resize(views_.size());
    view_extras_[slot] = ViewExtra{};
  }
}

size_t ClientReplicator::tracked_entities() const {
  return std::max(live_views_, soft_views_.size());
}

}  // namespace edgephys

namespace edgephys {

bool ClientReplicator::in_lockstep() const { return member_ != nullptr && member_->in; }

}  // namespace edgephys
