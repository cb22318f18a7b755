#include "protocol/replication_tracker.h"

#include <algorithm>

namespace edgephys {

ReplicationTracker::ReplicationTracker() = default;

bool ReplicationTracker::NeedsSend(uint32_t id, uint32_t version, double now,
                                   double resend_after_s) const {
  auto it = views_.find(id);
  if (it == views_.end()) return true;
  const EntityView& v = it->second;
  if (version <= v.acked) return false;
  if (version > v.sent) return true;
  return now - v.sent_at >= resend_after_s;
}

void ReplicationTracker::OnSent(uint16_t sequence, uint32_t id, uint32_t version, double now) {
  if (records_.empty()) records_.resize(kPacketRecords);  // on first use: most peers never need it
  PacketRecord& r = records_[sequence % kPacketRecords];
  if (!r.valid || r.sequence != sequence) {
    r.valid = true;
    r.sequence = sequence;
    r.entries.clear();
  }
  r.entries.emplace_back(id, version);
  EntityView& v = views_[id];
  v.sent = version;
  v.sent_at = now;
}

void ReplicationTracker::OnAcked(uint16_t sequence) {
  if (records_.empty()) return;
  PacketRecord& r = records_[sequence % kPacketRecords];
  if (!r.valid || r.sequence != sequence) return;
  for (const auto& [id, version] : r.entries) {
    auto it = views_.find(id);
    if (it != views_.end() && version > it->second.acked) it->second.acked = version;
  }
  r.valid = false;
  r.entries.clear();
}

void ReplicationTracker::MarkAcked(uint32_t id, uint32_t version) {
  EntityView& v = views_[id];
  v.acked = std::max(v.acked, version);
  v.sent = std::max(v.sent, version);
}

void ReplicationTracker::Forget(uint32_t id) { views_.erase(id); }

uint32_t ReplicationTracker::AckedVersion(uint32_t id) const {
  auto it = views_.find(id);
  return it == views_.end() ? 0 : it->second.acked;
}

}  // namespace edgephys
