#include "protocol/soft_delta_stream.h"

#include <algorithm>

#include "protocol/byte_io.h"
#include "protocol/replication_tracker.h"

namespace edgephys {

// ---- SoftDeltaSender ----

SoftDeltaSender::SoftDeltaSender(const SoftDeltaSenderConfig& config)
    : config_(config) {}

const SoftDeltaSender::Version* SoftDeltaSender::NewestAcked(const Track& t, uint32_t below,
                                                             size_t size, uint32_t before_ms,
                                                             bool need_older_time) const {
  const Version* best = nullptr;
  for (const Version& v : t.versions) {
    if (v.version == 0 || v.version >= below || !v.full() || v.q.size() != size) continue;
    if (need_older_time && static_cast<int32_t>(before_ms - v.time_ms) <= 0) continue;
    if (best == nullptr || v.version > best->version) best = &v;
  }
  return best;
}

bool SoftDeltaSender::Prepare(uint32_t id, uint32_t version, std::span<const Vec3f> nodes,
                              uint32_t time_ms, double now, double resend_after_s) {
  if (nodes.empty() || version == 0) return false;
  Track& t = tracks_[id];
  if (t.versions.empty()) t.versions.resize(kSoftHistory);
  Version& newest = t.versions[t.newest];
  if (newest.version == version) {
    if (newest.full() || now - newest.sent_at < resend_after_s) return false;
    ++stats_.resends;
    return true;
  }
  if (version == t.settled_version) return false;
  if (newest.version > version) {  // versions went back (a reset): start over
    for (Version& v : t.versions) v = Version{};
  }
  const size_t size = nodes.size() * 3;
  // Settled: the newest version sent is fully acknowledged (so the receiver displays it) and
  // every particle is within the threshold of it.
  if (const Version* acked = newest.version != 0 && newest.full() && newest.q.size() == size ? &newest : nullptr) {
    const double thr2 = static_cast<double>(config_.threshold_m) * config_.threshold_m;
    const double step = config_.step_m;
    bool within = true;
    for (size_t i = 0; i < nodes.size() && within; ++i) {
      const double dx = nodes[i].x - acked->q[i * 3] * step;
      const double dy = nodes[i].y - acked->q[i * 3 + 1] * step;
      const double dz = nodes[i].z - acked->q[i * 3 + 2] * step;
      within = dx * dx + dy * dy + dz * dz <= thr2;
    }
    if (within) {
      t.settled_version = version;
      ++stats_.settled;
      return false;
    }
  }
  // The oldest slot (or a free one) takes the new version.
  size_t slot = 0;
  for (size_t s = 0; s < t.versions.size(); ++s) {
    if (t.versions[s].version == 0) {
      slot = s;
      break;
    }
    if (t.versions[s].version < t.versions[slot].version) slot = s;
  }
  // Sticky lattice: a particle keeps the baseline's lattice point while the truth is within
  // kSoftStickyBound steps of it (Euclidean; the nearest point's own bound is sqrt(3)/2), so
  // particles jittering about a cell boundary cost nothing; otherwise the nearest point.
  const Version* base = NewestAcked(t, version, size, 0, false);
  if (base != nullptr) {
    sticky_.assign(base->q.begin(), base->q.end());  // a copy: `slot` may be the baseline's
  } else {
    sticky_.clear();
  }
  Version& v = t.versions[slot];
  v.version = version;
  v.time_ms = time_ms;
  v.sent_at = -1e9;
  v.acked_count = 0;
  v.q.resize(size);
  v.acked.assign(nodes.size(), 0);
  const double step = config_.step_m;
  const double bound2 = kSoftStickyBound * kSoftStickyBound * step * step;
  for (size_t i = 0; i < nodes.size(); ++i) {
    if (!sticky_.empty()) {
      const double dx = nodes[i].x - sticky_[i * 3] * step;
      const double dy = nodes[i].y - sticky_[i * 3 + 1] * step;
      const double dz = nodes[i].z - sticky_[i * 3 + 2] * step;
      if (dx * dx + dy * dy + dz * dz <= bound2) {
        std::copy_n(sticky_.begin() + static_cast<ptrdiff_t>(i * 3), 3, v.q.begin() + static_cast<ptrdiff_t>(i * 3));
        continue;
      }
    }
    v.q[i * 3] = SoftLattice(nodes[i].x, config_.step_m);
    v.q[i * 3 + 1] = SoftLattice(nodes[i].y, config_.step_m);
    v.q[i * 3 + 2] = SoftLattice(nodes[i].z, config_.step_m);
  }
  t.newest = slot;
  return true;
}

void SoftDeltaSender::BeginPayload(std::span<uint8_t> out, uint32_t time_ms) {
  out_ = out;
  time_ms_ = time_ms;
  pos_ = BeginSoftDeltaPayload(time_ms, out);
  pending_.clear();
}

bool SoftDeltaSender::AddRecords(uint32_t id, uint32_t* first) {
  auto it = tracks_.find(id);
  if (it == tracks_.end() || it->second.versions.empty() || pos_ == 0) return false;
  const Track& t = it->second;
  const Version& v = t.versions[t.newest];
  if (v.version == 0 || *first >= v.q.size() / 3) return false;
  SoftDeltaRecordInput in;
  in.entity_id = id;
  in.version = v.version;
  in.age_ms = time_ms_ - v.time_ms;
  in.q = v.q;
  in.first = *first;
  in.max_count = static_cast<uint32_t>(v.q.size() / 3) - *first;
  if (const Version* b = NewestAcked(t, v.version, v.q.size(), 0, false)) {
    in.refs.base = b->q;
    in.refs.base_distance = v.version - b->version;
    in.refs.dt_ms = v.time_ms - b->time_ms;
    if (const Version* b2 = NewestAcked(t, b->version, v.q.size(), b->time_ms, true)) {
      in.refs.base2 = b2->q;
      in.refs.base2_distance = b->version - b2->version;
      in.refs.base_dt_ms = b->time_ms - b2->time_ms;
    }
  }
  uint32_t count = 0;
  uint8_t mode = 0;
  const size_t n = EncodeSoftDeltaRecord(in, out_.subspan(pos_), &scratch_, &count, &mode);
  if (n == 0) return false;
  pos_ += n;
  pending_.push_back({id, v.version, *first, count});
  *first += count;
  ++stats_.records;
  stats_.bytes += n;
  if ((mode & 3) == kSoftKeyframe) ++stats_.keyframes;
  if ((mode & 3) == kSoftExtrapolate) ++stats_.extrapolated;
  return true;
}

size_t SoftDeltaSender::FinishPayload() { return pending_.empty() ? 0 : pos_; }

void SoftDeltaSender::OnSent(uint16_t sequence, double now) {
  if (records_.empty()) records_.resize(ReplicationTracker::kPacketRecords);  // on first use
  PacketRecord& r = records_[sequence % records_.size()];
  r.valid = true;
  r.sequence = sequence;
  r.entries.assign(pending_.begin(), pending_.end());
  for (const Entry& e : pending_) {
    auto it = tracks_.find(e.id);
    if (it == tracks_.end()) continue;
    for (Version& v : it->second.versions) {
      if (v.version == e.version) v.sent_at = now;
    }
  }
  pending_.clear();
}

void SoftDeltaSender::OnNotSent() { pending_.clear(); }

bool SoftDeltaSender::OnAcked(uint16_t sequence) {
  if (records_.empty()) return false;
  PacketRecord& r = records_[sequence % records_.size()];
  if (!r.valid || r.sequence != sequence) return false;
  r.valid = false;
  for (const Entry& e : r.entries) {
    auto it = tracks_.find(e.id);
    if (it == tracks_.end()) continue;
    for (Version& v : it->second.versions) {
      if (v.version != e.version) continue;
      const size_t end = std::min<size_t>(v.acked.size(), size_t{e.first} + e.count);
      for (size_t i = e.first; i < end; ++i) {
        if (v.acked[i] == 0) {
          v.acked[i] = 1;
          ++v.acked_count;
        }
      }
    }
  }
  return true;
}

void SoftDeltaSender::Forget(uint32_t id) { tracks_.erase(id); }

uint32_t SoftDeltaSender::AckedVersion(uint32_t id) const {
  auto it = tracks_.find(id);
  if (it == tracks_.end() || it->second.versions.empty()) return 0;
  const Version* v = NewestAcked(it->second, UINT32_MAX, it->second.versions[it->second.newest].q.size(), 0, false);
  return v != nullptr ? v->version : 0;
}

// ---- SoftDeltaReceiver ----

SoftDeltaReceiver::SoftDeltaReceiver(float step_m, uint32_t max_total, size_t max_bodies,
                                     size_t max_held_particles)
    : step_m_(step_m), max_total_(max_total), max_bodies_(max_bodies),
      max_held_particles_(max_held_particles) {}

const SoftDeltaReceiver::Held* SoftDeltaReceiver::Find(const Body& b, uint32_t version,
                                                       uint32_t first, uint32_t count) const {
  for (const Held& h : b.held) {
    if (h.version != version) continue;
    for (uint32_t i = first; i < first + count; ++i) {
      if (h.have[i] == 0) return nullptr;
    }
    return &h;
  }
  return nullptr;
}

void SoftDeltaReceiver::Release(Body& b) {
  for (Held& h : b.held) {
    if (!h.q.empty()) held_particles_ -= h.have.size();
  }
  b.held.clear();
}

Status SoftDeltaReceiver::Decode(std::span<const uint8_t> payload) {
  updates_.clear();
  ++stats_.payloads;
  if (payload.size() < kSoftDeltaHeaderSize || payload[0] != kSoftDeltaFormat) {
    ++stats_.malformed;
    return Status::Malformed("not a soft delta payload");
  }
  const uint32_t time_ms = LoadU32LE(payload.data() + 1);
  size_t pos = kSoftDeltaHeaderSize;
  if (pos == payload.size()) {
    ++stats_.malformed;
    return Status::Malformed("soft delta payload without records");
  }
  SoftDeltaRecord r;
  while (pos < payload.size()) {
    Status s = ParseSoftDeltaRecord(payload, time_ms, max_total_, &pos, &r);
    if (s.ok()) s = Apply(r);
    if (!s.ok()) {
      ++stats_.malformed;
      return s;
    }
  }
  return Status::Ok();
}

Status SoftDeltaReceiver::Apply(const SoftDeltaRecord& r) {
  auto it = bodies_.find(r.entity_id);
  if (it == bodies_.end()) {
    if (bodies_.size() >= max_bodies_) {
      ++stats_.over_capacity;
      return Status::Ok();
    }
    it = bodies_.try_emplace(r.entity_id).first;
  }
  Body& b = it->second;
  if (b.total != r.total) {  // a new body (or a new shape): nothing held applies
    // Updates this payload already reported for the old shape name particles it no longer has.
    std::erase_if(updates_, [&](const SoftDeltaUpdate& u) { return u.id == r.entity_id; });
    Release(b);
    b.total = r.total;
    b.display.assign(r.total, Vec3f{});
    b.shown.assign(r.total, 0);
  }
  if (b.held.empty()) b.held.resize(kSoftHistory);
  const uint8_t predictor = r.mode & 3;
  SoftDeltaRefs refs;
  if (predictor >= kSoftBaseline) {
    const Held* base = Find(b, r.base_version, r.first, r.count);
    const bool uses2 = SoftModeUsesBase2(r.mode);
    const Held* base2 = uses2 ? Find(b, r.base2_version, r.first, r.count) : nullptr;
    if (base == nullptr || (uses2 && base2 == nullptr)) {
      ++stats_.unknown_baseline;
      return Status::Ok();
    }
    refs.base = base->q;
    refs.dt_ms = r.time_ms - base->time_ms;
    if (base2 != nullptr) {
      refs.base2 = base2->q;
      refs.base_dt_ms = base->time_ms - base2->time_ms;
    }
  }
  // Where the version goes: its slot, a free one, or the lowest version's (if lower).
  Held* target = nullptr;
  Held* lowest = nullptr;
  for (Held& h : b.held) {
    if (h.version == r.version) {
      target = &h;
      break;
    }
    if (lowest == nullptr || h.version < lowest->version) lowest = &h;
  }
  if (target == nullptr) {
    if (lowest->version != 0 && lowest->version > r.version) {
      ++stats_.stale;
      return Status::Ok();
    }
    if (lowest->q.empty() && held_particles_ + r.total > max_held_particles_) {
      ++stats_.over_capacity;
      return Status::Ok();
    }
  }
  scratch_.resize(size_t{r.total} * 3);
  if (Status s = DecodeSoftDeltaResiduals(r, refs, scratch_); !s.ok()) return s;
  if (target == nullptr) {
    target = lowest;
    if (target->q.empty()) held_particles_ += r.total;
    target->version = r.version;
    target->time_ms = r.time_ms;
    target->q.resize(size_t{r.total} * 3);
    target->have.assign(r.total, 0);
  }
  std::copy(scratch_.begin() + size_t{r.first} * 3, scratch_.begin() + size_t{r.first + r.count} * 3,
            target->q.begin() + size_t{r.first} * 3);
  std::fill(target->have.begin() + r.first, target->have.begin() + r.first + r.count, 1);
  ++stats_.records;
  bool changed = false;
  for (uint32_t i = r.first; i < r.first + r.count; ++i) {
    if (b.shown[i] > r.version) continue;
    b.shown[i] = r.version;
    b.display[i] = {static_cast<float>(target->q[size_t{i} * 3] * static_cast<double>(step_m_)),
                    static_cast<float>(target->q[size_t{i} * 3 + 1] * static_cast<double>(step_m_)),
                    static_cast<float>(target->q[size_t{i} * 3 + 2] * static_cast<double>(step_m_))};
    changed = true;
  }
  if (changed) updates_.push_back({r.entity_id, r.first, r.count});
  return Status::Ok();
}

std::span<const Vec3f> SoftDeltaReceiver::Display(uint32_t id) const {
  auto it = bodies_.find(id);
  return it == bodies_.end() ? std::span<const Vec3f>() : std::span<const Vec3f>(it->second.display);
}

std::vector<uint32_t> SoftDeltaReceiver::HeldVersions(uint32_t id) const {
  std::vector<uint32_t> out;
  auto it = bodies_.find(id);
  if (it == bodies_.end()) return out;
  for (const Held& h : it->second.held) {
    if (h.version != 0) out.push_back(h.version);
  }
  std::sort(out.begin(), out.end());
  return out;
}

void SoftDeltaReceiver::Forget(uint32_t id) {
  auto it = bodies_.find(id);
  if (it == bodies_.end()) return;
  Release(it->second);
  bodies_.erase(it);
}

}  // namespace edgephys
