// Format 9, relay side: what lockstep (relay/lockstep.h) asks of one receiver's stream: whether
// its records make the same references as the room's canonical stream, which of its payloads are
// still in flight, and becoming a copy of the canonical stream when it leaves lockstep.
#include <algorithm>

#include "protocol/shared_delta_codec.h"

namespace edgephys {

bool SharedDeltaStream::SameBaselines(SharedDeltaStream& canonical, const SharedEntity& entity,
                                      uint32_t tick) {
  const uint32_t s = entity.slot();
  const uint32_t serial = entity.serial();
  if (serial == 0) return true;
  // The canonical stream holds no record of this occupant: its next send is a keyframe.
  if (s >= canonical.tracks_.size() || canonical.tracks_[s].serial != serial) return true;
  if (s >= tracks_.size() || tracks_[s].serial != serial) return false;
  Track& c = canonical.tracks_[s];
  Track& r = tracks_[s];
  canonical.Resolve(c, tick);
  Resolve(r, tick);
  const bool c_usable = c.Usable(c.acked_no);
  if (c_usable != r.Usable(r.acked_no)) return false;
  if (c_usable && !(c.acked_ref == r.acked_ref && c.acked_back1 == r.acked_back1 &&
                    c.acked_back2 == r.acked_back2 && c.acked_depth == r.acked_depth)) {
    return false;
  }
  // The sends since (each may become the baseline once acknowledged): same number (usability
  // counts them), same ticks and keys, all remembered.
  const uint32_t in_flight = c.next - c.acked_no;
  if (in_flight != r.next - r.acked_no || in_flight > kRememberedSends) return false;
  for (uint32_t k = 1; k <= in_flight; ++k) {
    const uint32_t ci = (c.acked_no + k - 1) % kRememberedSends;
    const uint32_t ri = (r.acked_no + k - 1) % kRememberedSends;
    const PayloadRecord* cp = canonical.SentPayload(c.sent_payload[ci]);
    const PayloadRecord* rp = SentPayload(r.sent_payload[ri]);
    if (cp == nullptr || rp == nullptr || cp->tick != rp->tick) return false;
    if (c.sent_back1[ci] != r.sent_back1[ri] || c.sent_back2[ci] != r.sent_back2[ri] ||
        c.sent_depth[ci] != r.sent_depth[ri]) {
      return false;
    }
  }
  return true;
}

void SharedDeltaStream::PayloadsAfter(uint32_t after_tick, std::vector<SentPayloadInfo>* out) const {
  if (payloads_.empty()) return;
  const size_t first = out->size();
  uint32_t newest = 0;  // the number of (*out)[first]
  for (uint32_t k = 0, no = payload_no_; k < kPayloadRing && no != 0; ++k, --no) {
    const PayloadRecord* p = SentPayload(no);
    if (p == nullptr) {
      if (no == payload_no_) continue;  // opened, never sent
      break;
    }
    if (static_cast<int32_t>(p->tick - after_tick) <= 0) break;
    if (newest == 0) newest = no;
    out->push_back({p->tick, p->acked, false, 0});
  }
  // The sequences of the unacknowledged ones (an acknowledged packet's record is cleared).
  for (const PacketRecord& r : records_) {
    if (!r.valid) continue;
    const PayloadRecord* p = SentPayload(r.payload);
    if (p == nullptr || p->acked) continue;
    const uint32_t back = newest - r.payload;
    if (back >= out->size() - first) continue;
    SentPayloadInfo& info = (*out)[first + back];
    info.has_sequence = true;
    info.sequence = r.sequence;
  }
}

void SharedDeltaStream::AdoptFrom(const SharedDeltaStream& canonical,
                                  std::span<const PayloadFix> fixes) {
  *this = canonical;
  for (PacketRecord& r : records_) r = PacketRecord{};
  for (const PayloadFix& f : fixes) {
    if (payloads_.empty()) break;
    PayloadRecord& p = payloads_[f.payload & (kPayloadRing - 1)];
    if (f.payload == 0 || p.number != f.payload) continue;
    p.acked = f.acked;
    if (!f.acked && f.has_sequence) {
      records_[f.sequence % kPacketRecords] = PacketRecord{true, f.sequence, f.payload};
    }
  }
  ++ack_epoch_;  // with an ack delay Resolve looks every time; this only keeps the count moving
}

}  // namespace edgephys
