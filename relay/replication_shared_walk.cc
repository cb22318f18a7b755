// ClientReplicator's format-9 walk without a bandwidth budget (relay/replication.h): one pass
// over the room's frame that decides and appends each entity as it goes, instead of a pass
// that collects candidates and a second that encodes them. Without a budget every candidate
// goes, in id order, so the two passes made the same appends in the same order; one pass
// touches each (receiver, entity) record once per tick while it is still in the core's cache
// (the walk is bound by loading them: docs/benchmarks.md, "Session 14: format 9's
// per-receiver walk"). The payloads are byte for byte those of the two-pass walk
// (relay/replication_walk_test.cc).
#include <cmath>

#include "relay/entity.h"
#include "relay/replication.h"

namespace edgephys {

void ClientReplicator::TickSharedEntities(const ReplicationFrame& frame, uint32_t self,
                                          double now, double resend_after,
                                          Connection* connection, PacketWriter* out,
                                          RelayCounters& counters) {
  using Need = DeltaEncoder::UpdateNeed;
  constexpr size_t kPrefetchAhead = 8;  // as TickEntities
  const size_t entity_count = frame.by_id.size();
  bool open = false;  // a payload is open (Begin ran): only once something is sent, as before
  // The room computed each entity's next due time for this tick (Room::ScheduleFrame) with the
  // same settings: use it instead of a class and a division per send.
  const bool scheduled = frame.schedule_now == now && frame.next_due.size() == entity_count &&
                         frame.schedule_basis == ScheduleBasisOf(config_);
  for (size_t i = 0; i < entity_count; ++i) {
    if (i + kPrefetchAhead < entity_count) {
      const uint32_t ahead = frame.by_id[i + kPrefetchAhead]->slot;
      if (ahead < views_.size()) {
        __builtin_prefetch(&views_[ahead]);
        __builtin_prefetch(reinterpret_cast<const char*>(&views_[ahead]) + sizeof(View) - 1);
      }
      shared_->Prefetch(ahead);
    }
    const Entity& e = *frame.by_id[i];
    if (e.owner == self && !include_own_) continue;
    View& v = ViewOf(e);
    if (now + kEpsilon < v.next_due || v.settled_version == e.version) continue;
    // This very version was sent within the resend time, in a payload that left: the stream
    // would answer "acknowledged within" or "in flight within" (the version held at that send's
    // tick is the current state): nothing to send, and its record need not be loaded. Not in
    // lockstep rooms, whose views and streams a leave replaces (AdoptCanonical).
    if (v.sent_version == e.version && now - v.last_sent < resend_after &&
        v.last_sent != failed_send_at_ && !include_own_) {
      continue;
    }
    const Need need = e.shared != nullptr
                          ? shared_->Need(e.id, *e.shared, e.state, config_.position_threshold_m,
                                          config_.rotation_threshold_deg, now, resend_after)
                          : Need::kSend;
    if (need == Need::kAckedWithin) v.settled_version = e.version;
    if (need != Need::kSend) continue;
    // The room coded the body once for every receiver; this appends it.
    auto add = [&]() {
      return e.shared != nullptr && e.prepared_valid && shared_->Add(e.id, *e.shared);
    };
    if (!open) {
      encoder_->Begin(payload_, time_ms_);
      open = true;
    }
    if (!add()) {
      Flush(now, connection, out, counters);
      encoder_->Begin(payload_, time_ms_);
      if (!add()) continue;
    }
    if (e.owner == self) ++own_in_payload_;  // include_own_: not counted as delivered
    if (lockstep_capture_ != nullptr) payload_owners_.push_back(e.owner);
    v.last_sent = now;
    v.sent_version = e.version;
    v.next_due = scheduled ? frame.next_due[i] : NextDue(e.id, IntervalOf(ClassOf(e, now)), now);
  }
  if (open) Flush(now, connection, out, counters);
}

}  // namespace edgephys
