// Format 9, relay side of one receiver (SharedDeltaStream, protocol/shared_delta_codec.h):
// selection against the room's versions, payload assembly by bit copy of the room's bodies,
// and the per-slot records that sends and acknowledgements update.
#include <algorithm>
#include <bit>
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

}  // namespace

// ================================ Stream ================================

SharedDeltaStream::SharedDeltaStream(const QuantizationParams& params,
                                     const SharedDeltaStreamOptions& options)
    : params_(params), options_(options), records_(kPacketRecords) {
  // Track::sends_since_keyframe is 16 bits.
  options_.keyframe_refresh_sends = std::min<uint32_t>(options_.keyframe_refresh_sends, 0xFFFF);
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
  if (++payload_no_ == 0) ++payload_no_;  // 0 names no payload
  // The payload ring (24 KiB) on the first payload, not before: an idle receiver's stream
  // stays small (relay/footprint_test.cc). Sends are recorded only after a Begin.
  if (payloads_.empty()) payloads_.resize(kPayloadRing);
  bits_ = out.size() > kStreamStart ? out.data() + kStreamStart : nullptr;
  bits_size_ = out.size() > kStreamStart ? out.size() - kStreamStart : 0;
  bit_pos_ = 0;
}

// As BitWriter::WriteBits (LSB-first; bits past the written ones in the bytes touched are
// zeroed), inline for the record loop; the caller has checked that the bits fit.
inline void SharedDeltaStream::WriteBits(uint64_t value, int bits) {
  while (bits > 0) {
    const int n = bits < 56 ? bits : 32;
    const uint64_t v = value & ((uint64_t{1} << n) - 1);
    const size_t byte = bit_pos_ >> 3;
    const int offset = static_cast<int>(bit_pos_ & 7);
    if (byte + 8 <= bits_size_) {
      uint64_t word;
      std::memcpy(&word, bits_ + byte, 8);
      word = (word & ((uint64_t{1} << offset) - 1)) | (v << offset);
      std::memcpy(bits_ + byte, &word, 8);
    } else {
      uint64_t rest = v;
      size_t pos = bit_pos_;
      for (int left = n; left > 0;) {
        const size_t b = pos >> 3;
        const int off = static_cast<int>(pos & 7);
        if (off == 0) bits_[b] = 0;
        const int take = left < 8 - off ? left : 8 - off;
        bits_[b] = static_cast<uint8_t>(bits_[b] | ((rest & ((1u << take) - 1)) << off));
        rest >>= take;
        left -= take;
        pos += static_cast<size_t>(take);
      }
    }
    bit_pos_ += static_cast<size_t>(n);
    value >>= n;
    bits -= n;
  }
}

namespace {

// Order-0 Exp-Golomb code of u as bits written LSB-first: n - 1 zeros, a one, then the low
// n - 1 bits of u + 1 (n = bit_width(u + 1)); as BitWriter::WriteExpGolomb(u, 0). Bits
// 2n - 1 <= 65: split in two (code bits, low bits) when past 56.
struct Code {
  uint64_t value[2];
  int bits[2];
};
inline Code ExpGolomb0(uint32_t u) {
  const uint64_t v = static_cast<uint64_t>(u) + 1;
  const int n = std::bit_width(v);
  const uint64_t low = v & ((uint64_t{1} << (n - 1)) - 1);
  if (2 * n - 1 <= 56) return {{(uint64_t{1} << (n - 1)) | (low << n), 0}, {2 * n - 1, 0}};
  return {{uint64_t{1} << (n - 1), low}, {n, n - 1}};
}

}  // namespace

void SharedDeltaStream::Resolve(Track& t, uint32_t tick) const {
  if (t.acked_no >= t.next) return;  // nothing newer than the acknowledged send
  // No payload acknowledged since the last look: its sends' flags are as they were then (a
  // send added since has a payload no ack has marked yet).
  if (t.resolved_epoch == ack_epoch_) return;
  t.resolved_epoch = ack_epoch_;
  const uint32_t oldest = t.next > kRememberedSends ? t.next - kRememberedSends : 0;
  // Newest first: the newest acknowledged send is the baseline.
  for (uint32_t no = t.next; no > oldest && no > t.acked_no; --no) {
    const uint32_t i = (no - 1) % kRememberedSends;
    const PayloadRecord* p = SentPayload(t.sent_payload[i]);
    if (p == nullptr || !AckDue(*p, tick)) continue;
    if (t.Usable(no)) {
      t.acked_no = no;
      t.acked_ref = p->tick;
      t.acked_back1 = t.sent_back1[i];
      t.acked_back2 = t.sent_back2[i];
      t.acked_depth = t.sent_depth[i];
    }
    return;
  }
}

bool SharedDeltaStream::Add(uint32_t id, SharedEntity& entity) {
  if (phase_ != Phase::kOpen || bits_ == nullptr) return false;
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
    track.sends_since_keyframe =
        static_cast<uint16_t>((id * 2654435761u) % options_.keyframe_refresh_sends);
  }
  Resolve(track, tick_);
  bool keyframe = true;
  if (track.Usable(track.acked_no)) {
    const uint32_t distance = tick_ - track.acked_ref;
    keyframe = !(distance >= 1 && distance <= kMaxReferenceDistance);
  }
  bool refresh = false;
  if (!keyframe && options_.keyframe_refresh_sends > 0 &&
      track.sends_since_keyframe >= options_.keyframe_refresh_sends) {
    keyframe = refresh = true;
  }
  SharedBaselineKey key;
  if (!keyframe) key = track.acked_key();
  const uint8_t* bits = nullptr;
  size_t nbits = 0;
  bool hit = false;
  if (!room->Body(entity, key, scratch_, &bits, &nbits, &hit)) {
    if (keyframe) return false;
    keyframe = true;  // the room no longer holds the baseline's versions
    key = SharedBaselineKey{};
    if (!room->Body(entity, key, scratch_, &bits, &nbits, &hit)) return false;
  }

  // The record: id gap, reference symbol (format 2's), then the room's body by bit copy.
  const Code gap = ExpGolomb0(count_ == 0 ? id : id - last_id_ - 1);
  uint32_t distance = 0;
  uint32_t sym = 1;  // keyframe
  if (!keyframe) {
    distance = tick_ - key.ref;
    sym = distance == prev_distance_
              ? 0
              : ZigZag(static_cast<int32_t>(distance) - static_cast<int32_t>(prev_distance_)) + 1;
  }
  const Code ref = ExpGolomb0(sym);
  const size_t total = static_cast<size_t>(gap.bits[0] + gap.bits[1] + ref.bits[0] + ref.bits[1]) +
                       nbits;
  if (nbits > kSharedBodyMaxBytes * 8 || bit_pos_ + total > bits_size_ * 8) return false;
  if (gap.bits[1] == 0 && ref.bits[1] == 0 && gap.bits[0] + ref.bits[0] <= 56) {
    WriteBits(gap.value[0] | (ref.value[0] << gap.bits[0]), gap.bits[0] + ref.bits[0]);
  } else {
    for (const Code& c : {gap, ref}) {
      WriteBits(c.value[0], c.bits[0]);
      WriteBits(c.value[1], c.bits[1]);
    }
  }
  for (size_t b = 0; nbits > 0; b += 7) {  // 56 bits a step from whole body bytes
    const int n = nbits < 56 ? static_cast<int>(nbits) : 56;
    uint64_t v = 0;
    if (b + 8 <= kSharedBodyMaxBytes) {
      std::memcpy(&v, bits + b, 8);
    } else {
      for (size_t i = 0; b + i < kSharedBodyMaxBytes && i < 8; ++i) {
        v |= static_cast<uint64_t>(bits[b + i]) << (8 * i);
      }
    }
    WriteBits(v, n);
    nbits -= static_cast<size_t>(n);
  }

  ++stats_.entities;
  if (hit) ++stats_.cache_hits;
  if (keyframe) {
    ++stats_.keyframes;
    if (refresh) ++stats_.refresh_keyframes;
    if (refresh || track.next > 0) track.sends_since_keyframe = 0;
  } else {
    prev_distance_ = distance;
    if (track.sends_since_keyframe < 0xFFFF) ++track.sends_since_keyframe;
  }
  const uint32_t send_no = track.next++;
  const uint32_t i = send_no % kRememberedSends;
  track.sent_payload[i] = payload_no_;  // the send's tick is its payload's (OnSent)
  if (keyframe) {
    track.sent_back1[i] = track.sent_back2[i] = 0;
    track.sent_depth[i] = 1;
  } else {  // distance <= kMaxReferenceDistance, and so is key.ref - key.s1 (an older record's)
    track.sent_back1[i] = static_cast<uint16_t>(tick_ - key.ref);
    track.sent_back2[i] = static_cast<uint16_t>(tick_ - key.s1);
    track.sent_depth[i] = static_cast<uint8_t>(std::min(key.depth + 1, 3));
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
  ++stats_.payloads;
  return PlaceRecordStream(p, kSharedDeltaHeaderSize, count_, kStreamStart, (bit_pos_ + 7) / 8);
}

void SharedDeltaStream::OnSent(uint16_t packet_sequence, double now) {
  if (phase_ != Phase::kFinished) return;
  phase_ = Phase::kSent;
  PacketRecord& r = records_[packet_sequence % kPacketRecords];
  r.valid = true;
  r.sequence = packet_sequence;
  r.payload = payload_no_;
  PayloadRecord& p = payloads_[payload_no_ & (kPayloadRing - 1)];
  p.number = payload_no_;
  p.tick = tick_;
  p.acked = false;
  p.sent_at = now;
}

void SharedDeltaStream::OnPacketAcked(uint16_t packet_sequence) {
  PacketRecord& r = records_[packet_sequence % kPacketRecords];
  if (!r.valid || r.sequence != packet_sequence) {
    ++stats_.acks_unmatched;
    return;
  }
  r.valid = false;
  PayloadRecord& p = payloads_[r.payload & (kPayloadRing - 1)];
  if (p.number != r.payload) {  // overwritten: as if lost
    ++stats_.acks_unmatched;
    return;
  }
  if (!p.acked) ++ack_epoch_;
  p.acked = true;
}

SharedDeltaStream::Track& SharedDeltaStream::ClaimTrack(uint32_t id, const SharedEntity& entity,
                                                         bool* created) {
  const uint32_t s = entity.slot();
  if (s >= tracks_.size()) {
    tracks_.resize(s + 1);
    track_ids_.resize(s + 1);
  }
  Track& t = tracks_[s];
  *created = t.serial != entity.serial();
  if (!*created) return t;
  FreeTrack(s);  // a previous occupant of the slot
  if (const uint32_t* old = slot_of_.Find(id); old != nullptr && *old != s) FreeTrack(*old);
  t.serial = entity.serial();
  t.resolved_epoch = ack_epoch_ - 1;  // never "resolved at this epoch" before its first look
  track_ids_[s] = id;
  *slot_of_.TryEmplace(id).first = s;
  ++live_tracks_;
  return t;
}

void SharedDeltaStream::FreeTrack(uint32_t slot) {
  Track& t = tracks_[slot];
  if (t.serial == 0) return;
  const uint32_t id = track_ids_[slot];
  if (const uint32_t* s = slot_of_.Find(id); s != nullptr && *s == slot) slot_of_.Erase(id);
  t = Track{};
  track_ids_[slot] = 0;
  --live_tracks_;
}

void SharedDeltaStream::Forget(uint32_t id) {
  if (const uint32_t* s = slot_of_.Find(id); s != nullptr) FreeTrack(*s);
}

SharedDeltaStream::UpdateNeed SharedDeltaStream::Need(uint32_t id, const SharedEntity& entity,
                                                      const EntityState& truth,
                                                      float pos_threshold_m,
                                                      float rot_threshold_deg, double now,
                                                      double resend_after_s) {
  (void)id;
  const uint32_t s = entity.slot();
  if (s >= tracks_.size() || tracks_[s].serial != entity.serial() || entity.serial() == 0) {
    return UpdateNeed::kSend;
  }
  Track& t = tracks_[s];
  const SharedDeltaRoom* room = entity.room();
  if (room == nullptr) return UpdateNeed::kSend;
  Resolve(t, room->tick());
  const double pos2 = static_cast<double>(pos_threshold_m) * pos_threshold_m;
  if (rot_threshold_deg != min_dot_for_deg_) {
    min_dot_for_deg_ = rot_threshold_deg;
    min_dot_ = std::cos(static_cast<double>(rot_threshold_deg) * (3.14159265358979323846 / 360.0));
  }
  auto within = [&](uint32_t ref) {
    return room->HeldWithin(entity, ref, truth, pos2, min_dot_, lattice_reach2_,
                            lattice_min_dot_);
  };
  if (t.Usable(t.acked_no) && within(t.acked_ref)) return UpdateNeed::kAckedWithin;
  // The newest send, if it left, is not acknowledged yet and is still within its resend time.
  if (t.next > t.acked_no) {
    const PayloadRecord* p = SentPayload(t.sent_payload[(t.next - 1) % kRememberedSends]);
    if (p != nullptr && !AckDue(*p, room->tick()) && now - p->sent_at < resend_after_s &&
        within(p->tick)) {
      return UpdateNeed::kInFlightWithin;
    }
  }
  return UpdateNeed::kSend;
}

StreamNeed SharedDeltaStateStream::Want(const StreamEntity& e, double now, double resend_after_s,
                                        uint8_t*) {
  if (e.shared == nullptr) return StreamNeed::kSend;
  return ToStreamNeed(codec_.Need(e.id, *e.shared, *e.state, thresholds_.position_m,
                                  thresholds_.rotation_deg, now, resend_after_s));
}

bool SharedDeltaStateStream::Add(const StreamEntity& e, uint8_t) {
  // The room codes the body once for every receiver.
  return e.shared != nullptr && e.prepared != nullptr && codec_.Add(e.id, *e.shared);
}

void SharedDeltaStateStream::Count(bool sent, StreamCounts& counts) {
  const SharedDeltaStreamStats& st = codec_.stats();
  if (sent) {
    counts.shared_bodies_cached += st.cache_hits - hits_counted_;
    counts.shared_bodies_coded += (st.entities - entities_counted_) - (st.cache_hits - hits_counted_);
  }
  hits_counted_ = st.cache_hits;
  entities_counted_ = st.entities;
}

}  // namespace edgephys
