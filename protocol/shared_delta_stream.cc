// Format 9, relay side of one receiver (SharedDeltaStream, protocol/shared_delta_codec.h):
// selection against the room's versions, payload assembly by bit copy of the room's bodies,
// and the per-slot records that sends and acknowledgements update.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "protocol/byte_io.h"
#include "protocol/delta_prediction.h"
#include "protocol/shared_delta_codec.h"

namespace edgephys {
namespace {

using namespace delta_internal;  // NOLINT

constexpr size_t kCountReserve = 3;  // varint count reserved while encoding (< 2^21)
constexpr size_t kStreamStart = kSharedDeltaHeaderSize + kCountReserve;
constexpr size_t kPacketRecords = 128;

}  // namespace

// ================================ Stream ================================

SharedDeltaStream::SharedDeltaStream(const QuantizationParams& params,
                                     const SharedDeltaStreamOptions& options)
    : params_(params), options_(options), records_(kPacketRecords) {
  const double reach = 0.5 * std::sqrt(3.0) * params_.step * 1.01;
  lattice_reach2_ = reach * reach;
  const double bound_rad =
      params_.config.rotation_error_deg * 1.01 * (3.14159265358979323846 / 180.0);
  lattice_min_dot_ = std::cos(std::min(bound_rad, 3.14159265358979323846) / 2.0);
}

void SharedDeltaStream::Begin(std::span<uint8_t> out, uint32_t /*time_ms*/) {
  phase_ = Phase::kOpen;
  out_ = out;
  room_ = nullptr;
  count_ = 0;
  last_id_ = 0;
  prev_distance_ = 1;
  pending_ids_.clear();
  if (pending_ids_.capacity() < max_packet_ids_) pending_ids_.reserve(max_packet_ids_);
  writer_ = out.size() > kStreamStart ? BitWriter(out.subspan(kStreamStart)) : BitWriter();
}

bool SharedDeltaStream::Add(uint32_t id, SharedEntity& entity) {
  if (phase_ != Phase::kOpen || out_.size() <= kStreamStart) return false;
  const SharedDeltaRoom* room = entity.room();
  if (room == nullptr) return false;
  if (count_ == 0) {
    room_ = room;
    tick_ = room->tick();
  } else if (room != room_ || room->tick() != tick_ || id <= last_id_) {
    return false;
  }
  if (count_ >= (size_t{1} << 21) - 1) return false;

  if (entity.serial() == 0) return false;
  bool created = false;
  Track& track = ClaimTrack(id, entity, &created);
  if (created && options_.keyframe_refresh_sends > 0) {
    track.sends_since_keyframe = (id * 2654435761u) % options_.keyframe_refresh_sends;
  }
  bool keyframe = true;
  if (track.Usable(track.acked_no)) {
    const uint32_t distance = tick_ - track.acked_key.ref;
    keyframe = !(distance >= 1 && distance <= kMaxReferenceDistance);
  }
  bool refresh = false;
  if (!keyframe && options_.keyframe_refresh_sends > 0 &&
      track.sends_since_keyframe >= options_.keyframe_refresh_sends) {
    keyframe = refresh = true;
  }
  SharedBaselineKey key;
  if (!keyframe) key = track.acked_key;
  const uint8_t* bits = nullptr;
  size_t nbits = 0;
  bool hit = false;
  if (!room->Body(entity, key, scratch_, &bits, &nbits, &hit)) {
    if (keyframe) return false;
    keyframe = true;  // the room no longer holds the baseline's versions
    key = SharedBaselineKey{};
    if (!room->Body(entity, key, scratch_, &bits, &nbits, &hit)) return false;
  }

  const size_t mark = writer_.bit_position();
  BitWriter& w = writer_;
  bool ok = count_ == 0 ? w.WriteExpGolomb(id, 0) : w.WriteExpGolomb(id - last_id_ - 1, 0);
  uint32_t distance = 0;
  if (keyframe) {
    ok = ok && w.WriteExpGolomb(1, 0);
  } else {
    distance = tick_ - key.ref;
    const uint32_t sym =
        distance == prev_distance_
            ? 0
            : ZigZag(static_cast<int32_t>(distance) - static_cast<int32_t>(prev_distance_)) + 1;
    ok = ok && w.WriteExpGolomb(sym, 0);
  }
  ok = ok && w.AppendBits({bits, kSharedBodyMaxBytes}, nbits);
  if (!ok) {
    writer_.Rewind(mark);
    return false;
  }

  ++stats_.entities;
  if (hit) ++stats_.cache_hits;
  if (keyframe) {
    ++stats_.keyframes;
    if (refresh) ++stats_.refresh_keyframes;
    if (refresh || track.next > 0) track.sends_since_keyframe = 0;
  } else {
    prev_distance_ = distance;
    ++track.sends_since_keyframe;
  }
  const uint32_t send_no = track.next++;
  if (keyframe) {
    pending_ids_.push_back({entity.slot(), entity.serial(), send_no, tick_, tick_, 1});
  } else {
    pending_ids_.push_back({entity.slot(), entity.serial(), send_no, key.ref, key.s1,
                            static_cast<uint8_t>(std::min(key.depth + 1, 3))});
  }
  last_id_ = id;
  ++count_;
  return true;
}

size_t SharedDeltaStream::Finish() {
  if (phase_ != Phase::kOpen || count_ == 0) return 0;
  phase_ = Phase::kFinished;
  uint8_t* p = out_.data();
  const SharedDeltaParams& prm = room_->params();
  p[0] = kSharedDeltaStateFormat;
  StoreU32LE(p + 1, room_->time_ms());
  StoreU32LE(p + 5, tick_);
  StoreU16LE(p + 9, PackParams(prm.k, prm.mask, prm.order));
  uint8_t cnt[5];
  const size_t cnt_size = PutVarint32(static_cast<uint32_t>(count_), cnt);
  std::memcpy(p + kSharedDeltaHeaderSize, cnt, cnt_size);
  const size_t body = writer_.byte_size();
  const size_t dst = kSharedDeltaHeaderSize + cnt_size;
  std::memmove(p + dst, p + kStreamStart, body);
  ++stats_.payloads;
  return dst + body;
}

void SharedDeltaStream::OnSent(uint16_t packet_sequence, double now) {
  if (phase_ != Phase::kFinished) return;
  phase_ = Phase::kSent;
  PacketRecord& r = records_[packet_sequence % kPacketRecords];
  r.valid = true;
  r.sequence = packet_sequence;
  r.tick = tick_;
  max_packet_ids_ = std::max(max_packet_ids_, pending_ids_.size());
  if (entries_.size() < kEntryRingPayloads * max_packet_ids_) {
    // Grow (rarely: the largest payload so far grew); the payloads in flight lose their acks.
    size_t capacity = 1024;
    while (capacity < kEntryRingPayloads * max_packet_ids_) capacity *= 2;
    entries_.assign(capacity, PacketEntry{});
    for (PacketRecord& old : records_) old.valid = old.valid && &old == &r;
  }
  const size_t mask = entries_.size() - 1;
  r.begin = entries_head_;
  r.count = static_cast<uint32_t>(pending_ids_.size());
  for (const PacketEntry& p : pending_ids_) entries_[entries_head_++ & mask] = p;
  for (const PacketEntry& p : pending_ids_) {
    Track& t = tracks_[p.slot];
    if (t.serial != p.serial || !t.Usable(p.send_no + 1)) continue;
    if (t.sent_no == 0 || p.send_no + 1 > t.sent_no) {
      t.sent_no = p.send_no + 1;
      t.sent_ref = tick_;
      t.sent_at = now;
      t.sent_acked = false;
    }
  }
}

void SharedDeltaStream::OnPacketAcked(uint16_t packet_sequence) {
  PacketRecord& r = records_[packet_sequence % kPacketRecords];
  if (!r.valid || r.sequence != packet_sequence) {
    ++stats_.acks_unmatched;
    return;
  }
  r.valid = false;
  if (entries_head_ - r.begin > entries_.size()) {  // overwritten: as if lost
    ++stats_.acks_unmatched;
    return;
  }
  const size_t mask = entries_.size() - 1;
  for (uint64_t i = r.begin; i < r.begin + r.count; ++i) {
    const PacketEntry& p = entries_[i & mask];
    Track& t = tracks_[p.slot];
    if (t.serial != p.serial) {  // gone (Forget) or the slot has another occupant now
      ++stats_.acks_unmatched;
      continue;
    }
    const uint32_t no = p.send_no + 1;
    if (!t.Usable(no)) continue;  // overwritten: the client may no longer hold it
    if (t.sent_no == no) t.sent_acked = true;
    if (no > t.acked_no) {
      t.acked_no = no;
      t.acked_key = {r.tick, p.s1, p.s2, p.depth};
    }
  }
}

SharedDeltaStream::Track& SharedDeltaStream::ClaimTrack(uint32_t id, const SharedEntity& entity,
                                                         bool* created) {
  const uint32_t s = entity.slot();
  if (s >= tracks_.size()) tracks_.resize(s + 1);
  Track& t = tracks_[s];
  *created = t.serial != entity.serial();
  if (!*created) return t;
  FreeTrack(s);  // a previous occupant of the slot
  if (const uint32_t* old = slot_of_.Find(id); old != nullptr && *old != s) FreeTrack(*old);
  t.serial = entity.serial();
  t.id = id;
  *slot_of_.TryEmplace(id).first = s;
  ++live_tracks_;
  return t;
}

void SharedDeltaStream::FreeTrack(uint32_t slot) {
  Track& t = tracks_[slot];
  if (t.serial == 0) return;
  if (const uint32_t* s = slot_of_.Find(t.id); s != nullptr && *s == slot) slot_of_.Erase(t.id);
  t = Track{};
  --live_tracks_;
}

void SharedDeltaStream::Forget(uint32_t id) {
  if (const uint32_t* s = slot_of_.Find(id); s != nullptr) FreeTrack(*s);
}

SharedDeltaStream::UpdateNeed SharedDeltaStream::Need(uint32_t id, const SharedEntity& entity,
                                                      const EntityState& truth,
                                                      float pos_threshold_m,
                                                      float rot_threshold_deg, double now,
                                                      double resend_after_s) const {
  (void)id;
  const uint32_t s = entity.slot();
  if (s >= tracks_.size() || tracks_[s].serial != entity.serial() || entity.serial() == 0) {
    return UpdateNeed::kSend;
  }
  const Track& t = tracks_[s];
  const double pos2 = static_cast<double>(pos_threshold_m) * pos_threshold_m;
  if (rot_threshold_deg != min_dot_for_deg_) {
    min_dot_for_deg_ = rot_threshold_deg;
    min_dot_ = std::cos(static_cast<double>(rot_threshold_deg) * (3.14159265358979323846 / 360.0));
  }
  const SharedDeltaRoom* room = entity.room();
  if (room == nullptr) return UpdateNeed::kSend;
  auto within = [&](uint32_t ref) {
    return room->HeldWithin(entity, ref, truth, pos2, min_dot_, lattice_reach2_,
                            lattice_min_dot_);
  };
  if (t.Usable(t.acked_no) && within(t.acked_key.ref)) return UpdateNeed::kAckedWithin;
  if (t.Usable(t.sent_no) && !t.sent_acked && now - t.sent_at < resend_after_s &&
      within(t.sent_ref)) {
    return UpdateNeed::kInFlightWithin;
  }
  return UpdateNeed::kSend;
}

}  // namespace edgephys
