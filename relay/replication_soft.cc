// ClientReplicator's soft bodies: format 11 (residuals against acknowledged versions,
// protocol/soft_delta_stream.h), at
// soft_touched_hz while a hand touches a body, and the new world's first particles at once
// after a PhyS failover. The rest of the class is in replication.cc.
#include <algorithm>
#include <cmath>

#include "relay/entity.h"
#include "relay/replication.h"

namespace edgephys {

bool ClientReplicator::Resumed(const Entity& e, const SoftView& v, double now) {
  // After a PhyS failover the receivers get the new world's first particles at once: the jump
  // they see across the failover is then one physics step of the body's own motion, not the
  // up to a send interval's worth a later version would carry.
  return !e.resumed_nodes.empty() && e.nodes_resumed_at > v.sent_at &&
         now - e.nodes_resumed_at <= Entity::kResumeWindowS &&
         e.resumed_nodes.size() == e.nodes.size();
}

bool ClientReplicator::SoftTouched(const Entity& e) const {
  if (e.held_by != 0 || e.touching > 0) return true;
  if (hands_ == nullptr || hands_->empty()) return false;
  Vec3f lo = e.nodes[0], hi = e.nodes[0];
  for (const Vec3f& p : e.nodes) {
    lo = {std::min(lo.x, p.x), std::min(lo.y, p.y), std::min(lo.z, p.z)};
    hi = {std::max(hi.x, p.x), std::max(hi.y, p.y), std::max(hi.z, p.z)};
  }
  const float m = config_.soft_touch_margin_m;
  for (const Vec3f& h : *hands_) {
    if (h.x < lo.x - m || h.x > hi.x + m || h.y < lo.y - m || h.y > hi.y + m ||
        h.z < lo.z - m || h.z > hi.z + m) {
      continue;
    }
    for (const Vec3f& p : e.nodes) {  // within reach of a particle
      const float dx = p.x - h.x, dy = p.y - h.y, dz = p.z - h.z;
      if (dx * dx + dy * dy + dz * dz <= m * m) return true;
    }
  }
  return false;
}

bool ClientReplicator::FlushSoft(double now, Connection& connection, PacketWriter& out,
                                 RelayCounters& counters) {
  const size_t size = soft_->FinishPayload();
  if (size == 0) return false;
  Result<uint16_t> seq = connection.SendUnreliable({payload_.data(), size}, now, out);
  if (seq.ok()) {
    soft_->OnSent(*seq, now);
    RelayCounters::Inc(counters.entity_updates_sent);
  } else {
    soft_->OnNotSent();
  }
  budget_bytes_ -= static_cast<double>(size) + kPacketOverhead;
  soft_->BeginPayload(payload_, time_ms_);
  return true;
}

void ClientReplicator::TickSoftBodies(const ReplicationFrame& frame, uint32_t self, double now,
                                      double resend_after, Connection& connection,
                                      PacketWriter& out, RelayCounters& counters) {
  hands_ = &frame.hands;
  soft_due_.clear();
  for (const Entity* e : frame.soft) {  // by id
    if (e->nodes_version == 0 || e->owner == self || e->nodes.empty()) continue;
    SoftView& v = soft_views_[e->id];
    if (now + kEpsilon < v.next_due && !Resumed(*e, v, now)) continue;
    soft_due_.emplace_back(e->id, e);
  }
  if (soft_due_.empty()) return;
  soft_->BeginPayload(payload_, time_ms_);
  for (const auto& [id, e] : soft_due_) {
    if (config_.bandwidth_budget_bytes_per_s > 0 && budget_bytes_ <= 0) break;
    SoftView& v = soft_views_[id];
    const bool resumed = Resumed(*e, v, now);
    const std::vector<Vec3f>& nodes = resumed ? e->resumed_nodes : e->nodes;
    const uint32_t version = resumed ? e->resumed_version : e->nodes_version;
    v.sent_at = now;  // considered: a resumed version goes out once (or not, if settled)
    if (!soft_->Prepare(id, version, nodes, time_ms_, now, resend_after)) continue;
    uint32_t first = 0;
    for (int chunks = 0; first < nodes.size() && chunks < 64; ++chunks) {
      if (soft_->AddRecords(id, &first)) continue;
      if (!FlushSoft(now, connection, out, counters)) break;  // not even an empty payload fits one
    }
    const double hz = config_.fixed_rate_hz > 0 ? config_.fixed_rate_hz
                      : SoftTouched(*e)         ? config_.soft_touched_hz
                                                : config_.normal_hz;
    const double interval = 1.0 / hz;
    v.next_due += interval;
    if (v.next_due < now - interval || v.next_due > now + interval) v.next_due = now + interval;
  }
  (void)FlushSoft(now, connection, out, counters);
}

}  // namespace edgephys
