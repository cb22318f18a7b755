#include "protocol/delta_codec.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#include "protocol/byte_io.h"
#include "protocol/delta_prediction.h"

namespace edgephys {
namespace {

constexpr size_t kCountReserve = 3;  // varint count reserved while encoding (< 2^21)
constexpr size_t kStreamStart = kDeltaHeaderSize + kCountReserve;
constexpr size_t kPacketRecords = 128;
constexpr int kMaxK = 7;
// The adaptive parameters' statistics are gathered on one delta record in this many (they
// only rank the candidate orders and k; sampling cuts most of the encoder's cost).
constexpr uint64_t kStatsSampleEvery = 4;

}  // namespace


using namespace delta_internal;  // NOLINT

// ================================ Encoder ================================

DeltaEncoder::DeltaEncoder(const QuantizationParams& params, const DeltaEncoderOptions& options)
    : params_(params), options_(options), records_(kPacketRecords) {
  // A truth that quantises to a state lies within the quantisation error of that state's
  // dequantised value: half a cell's diagonal in position, the rotation bound in angle. The
  // 1 % slack only makes Need quantise a little more often than needed (the exact lattice
  // comparison decides).
  const double reach = 0.5 * std::sqrt(3.0) * params_.step * 1.01;
  lattice_reach2_ = reach * reach;
  const double bound_rad =
      params_.config.rotation_error_deg * 1.01 * (std::numbers::pi / 180.0);
  lattice_min_dot_ = std::cos(std::min(bound_rad, std::numbers::pi) / 2.0);
}

const DeltaEncoder::Entry* DeltaEncoder::NewestAcked(const Track& t) const {
  if (t.newest_acked == kNoSlot) return nullptr;
  const Entry& e = t.ring[t.newest_acked];
  const uint32_t distance = counter_ - e.counter;
  if (distance < 1 || distance > kMaxReferenceDistance) return nullptr;
  return &e;
}

void DeltaEncoder::ChooseParams() {
  for (int f = 0; f < 2; ++f) {
    double best = std::numeric_limits<double>::infinity();
    for (int o = 0; o < 3; ++o) {
      for (int k = 0; k <= kMaxK; ++k) {
        const double full = costs_.full[f][o][k];
        const double masked = costs_.masked[f][o][k];
        if (full <= 0 && masked <= 0) continue;  // no statistics yet
        if (full < best) {
          best = full;
          order_[f] = o;
          k_[f] = k;
          mask_[f] = false;
        }
        if (masked < best) {
          best = masked;
          order_[f] = o;
          k_[f] = k;
          mask_[f] = true;
        }
      }
    }
  }
}

void DeltaEncoder::Begin(std::span<uint8_t> out, uint32_t time_ms) {
  if (payload_used_) ++counter_;
  payload_used_ = false;
  phase_ = Phase::kOpen;
  out_ = out;
  time_ms_ = time_ms;
  count_ = 0;
  last_id_ = 0;
  prev_distance_ = 1;
  pending_ids_.clear();
  if (pending_ids_.capacity() < max_packet_ids_) pending_ids_.reserve(max_packet_ids_);
  packet_costs_ = CostTable{};
  packet_max_zigzag_[0] = packet_max_zigzag_[1] = 0;
  packet_residuals_[0] = packet_residuals_[1] = 0;
  ChooseParams();
  writer_ = out.size() > kStreamStart ? BitWriter(out.subspan(kStreamStart)) : BitWriter();
}

PreparedState PrepareState(const QuantizationParams& params, const EntityState& truth,
                           bool with_float) {
  PreparedState s;
  s.position_exact = QuantizePosition(params, truth.position, &s.q.position);
  s.rotation_ok = QuantizeRotation(params, truth.rotation, &s.q.rotation);
  s.rot4 = RotationToInt4(params, s.q.rotation);
  if (with_float) {
    s.position = DequantizePosition(params, s.q.position);
    s.rotation = DequantizeRotation(params, s.q.rotation);
    s.has_float = true;
  }
  s.step = params.step;
  for (int a = 0; a < 3; ++a) s.origin[a] = params.origin[a];
  s.rotation_max = params.rotation_max;
  return s;
}

bool DeltaEncoder::Add(const EntityState& truth, const PreparedState* prepared) {
  const uint32_t record_time_ms = time_ms_;  // the time the record holds
  if (phase_ != Phase::kOpen || out_.size() <= kStreamStart) return false;
  const uint32_t id = truth.entity_id;
  if (count_ > 0 && id <= last_id_) return false;
  if (count_ >= (size_t{1} << 21) - 1) return false;  // count varint reserve (3 bytes)

  PreparedState own;
  if (prepared == nullptr || !SameLattice(*prepared, params_)) {
    own = PrepareState(params_, truth, /*with_float=*/false);  // dequantised lazily, if asked
    prepared = &own;
  }
  const QuantizedState& q = prepared->q;
  const bool pos_exact = prepared->position_exact;
  const bool rot_ok = prepared->rotation_ok;

  auto [track_ptr, created] = tracks_.TryEmplace(id);
  Track& track = *track_ptr;
  if (created && options_.keyframe_refresh_sends > 0) {
    // Stagger refreshes by id so that entities created together do not refresh together.
    track.sends_since_keyframe = (id * 2654435761u) % options_.keyframe_refresh_sends;
  }
  const Entry* base_entry = NewestAcked(track);
  bool keyframe = base_entry == nullptr;
  bool refresh = false;
  if (!keyframe && options_.keyframe_refresh_sends > 0 &&
      track.sends_since_keyframe >= options_.keyframe_refresh_sends) {
    keyframe = refresh = true;
  }
  History base_hist;
  if (!keyframe) base_hist = base_entry->hist;  // copy: its slot may be overwritten below

  const size_t mark = writer_.bit_position();
  BitWriter& w = writer_;
  bool ok = count_ == 0 ? w.WriteExpGolomb(id, 0) : w.WriteExpGolomb(id - last_id_ - 1, 0);
  // Bit positions after each part (the breakdown of stats().record_part_bits).
  size_t at_id = w.bit_position(), at_ref = at_id, at_mask = at_id, at_pos = at_id;
  uint32_t distance = 0;
  // Residual statistics of this record, committed only if it fits.
  bool sample = false;  // add_full / add_masked filled (one delta record in kStatsSampleEvery)
  double add_full[2][3][8];
  double add_masked[2][3][8];
  uint32_t max_zz[2] = {0, 0};
  uint64_t eg_bits = 0;
  int n_residuals[2] = {0, 0};

  if (keyframe) {
    ok = ok && w.WriteExpGolomb(1, 0);
    at_ref = at_mask = at_pos = w.bit_position();
    ok = ok && WriteKeyframeState(w, params_, q);
  } else {
    distance = counter_ - base_entry->counter;
    const uint32_t sym =
        distance == prev_distance_
            ? 0
            : ZigZag(static_cast<int32_t>(distance) - static_cast<int32_t>(prev_distance_)) + 1;
    ok = ok && w.WriteExpGolomb(sym, 0);
    at_ref = w.bit_position();

    // Residuals for every order (statistics for the adaptive parameters) on one delta record
    // in kStatsSampleEvery; otherwise only for the orders in use. Code the chosen one.
    const int po = order_[0], ro = order_[1];
    sample = records_added_++ % kStatsSampleEvery == 0;
    Residuals res;
    ComputeResiduals(params_, base_hist, q, record_time_ms, order_, sample, &res);
    if (sample) {
      for (int o = 0; o < 3; ++o) {
        for (int k = 0; k <= kMaxK; ++k) {
          double pos_bits = 0, rot_bits = res.rot_same[o] ? 1 : 3;
          for (int a = 0; a < 3; ++a) {
            pos_bits += ExpGolombBits(ZigZag(res.pos[o][a]), k);
            rot_bits += ExpGolombBits(ZigZag(res.rot[o][a]), k);
          }
          add_full[0][o][k] = pos_bits;
          add_full[1][o][k] = rot_bits;
          add_masked[0][o][k] = 1 + (res.pos_zero[o] ? 0 : pos_bits);
          add_masked[1][o][k] = 1 + (res.rot_zero[o] ? 0 : rot_bits);
        }
      }
    }
    DeltaBodyMarks marks;
    ok = ok && WriteDeltaBody(w, res, q, k_, mask_, order_, &marks);
    at_mask = marks.at_mask;
    at_pos = marks.at_pos;
    if (marks.pos_coded) {
      for (int a = 0; a < 3; ++a) {
        eg_bits += ExpGolombBits(ZigZag(res.pos[po][a]), k_[0]);
        max_zz[0] = std::max(max_zz[0], ZigZag(res.pos[po][a]));
      }
      n_residuals[0] = 3;
    }
    if (marks.rot_coded) {
      for (int c = 0; c < 3; ++c) {
        eg_bits += ExpGolombBits(ZigZag(res.rot[ro][c]), k_[1]);
        max_zz[1] = std::max(max_zz[1], ZigZag(res.rot[ro][c]));
      }
      n_residuals[1] = 3;
    }
  }
  const size_t at_rot = w.bit_position();
  if (!ok) {
    writer_.Rewind(mark);
    return false;
  }

  // Committed: record the state as sent-in-this-payload.
  last_bits_[kRecordPartId] = static_cast<uint32_t>(at_id - mark);
  last_bits_[kRecordPartReference] = static_cast<uint32_t>(at_ref - at_id);
  last_bits_[kRecordPartKeyframe] = keyframe ? static_cast<uint32_t>(at_rot - at_ref) : 0;
  last_bits_[kRecordPartMask] = keyframe ? 0 : static_cast<uint32_t>(at_mask - at_ref);
  last_bits_[kRecordPartPosition] = keyframe ? 0 : static_cast<uint32_t>(at_pos - at_mask);
  last_bits_[kRecordPartRotation] = keyframe ? 0 : static_cast<uint32_t>(at_rot - at_pos);
  for (size_t i = 0; i < kRecordPartCount; ++i) stats_.record_part_bits[i] += last_bits_[i];
  if (!pos_exact) ++stats_.positions_clamped;
  if (!rot_ok) ++stats_.rotations_invalid;
  ++stats_.entities;
  if (keyframe) {
    ++stats_.keyframes;
    if (refresh) ++stats_.refresh_keyframes;
    if (refresh || track.next > 0) track.sends_since_keyframe = 0;
  } else {
    prev_distance_ = distance;
    ++track.sends_since_keyframe;
    for (int f = 0; f < 2; ++f) {
      for (int o = 0; sample && o < 3; ++o) {
        for (int k = 0; k <= kMaxK; ++k) {
          packet_costs_.full[f][o][k] += add_full[f][o][k];
          packet_costs_.masked[f][o][k] += add_masked[f][o][k];
        }
      }
      packet_max_zigzag_[f] = std::max(packet_max_zigzag_[f], max_zz[f]);
      packet_residuals_[f] += static_cast<uint64_t>(n_residuals[f]);
    }
    stats_.residual_bits_exp_golomb += eg_bits;
  }
  const auto slot = static_cast<uint8_t>(track.next % kDeltaBaselineWindow);
  Entry& e = track.ring[slot];
  ++track.next;
  if (track.newest_acked == slot) track.newest_acked = kNoSlot;  // the oldest entry goes
  if (track.newest_sent == slot) track.newest_sent = kNoSlot;
  e.valid = true;
  e.acked = false;
  e.sent = false;
  e.counter = counter_;
  e.q = q;
  e.has_float = prepared->has_float;
  if (e.has_float) {
    e.position = prepared->position;
    e.rotation = prepared->rotation;
  }
  e.hist = ExtendHistory(keyframe ? nullptr : &base_hist, MakeSample(q, prepared->rot4, record_time_ms));
  pending_ids_.emplace_back(id, slot);
  payload_used_ = true;
  last_id_ = id;
  ++count_;
  return true;
}

size_t DeltaEncoder::Finish() {
  if (phase_ != Phase::kOpen || count_ == 0) return 0;
  phase_ = Phase::kFinished;
  uint8_t* p = out_.data();
  p[0] = kDeltaStateFormat;
  StoreU32LE(p + 1, time_ms_);
  StoreU16LE(p + 5, static_cast<uint16_t>(counter_));
  StoreU16LE(p + 7, PackParams(k_, mask_, order_));
  const size_t size = PlaceRecordStream(p, kDeltaHeaderSize, count_, kStreamStart,
                                        writer_.byte_size());

  // Adaptive statistics (decayed) and the fixed-width comparison.
  for (int f = 0; f < 2; ++f) {
    for (int o = 0; o < 3; ++o) {
      for (int k = 0; k <= kMaxK; ++k) {
        costs_.full[f][o][k] = 0.5 * costs_.full[f][o][k] + packet_costs_.full[f][o][k];
        costs_.masked[f][o][k] = 0.5 * costs_.masked[f][o][k] + packet_costs_.masked[f][o][k];
      }
    }
    if (packet_residuals_[f] > 0) {
      stats_.residual_bits_fixed_width +=
          5 + packet_residuals_[f] * static_cast<uint64_t>(std::bit_width(packet_max_zigzag_[f]));
    }
  }
  ++stats_.payloads;
  return size;
}

void DeltaEncoder::OnSent(uint16_t packet_sequence, double now) {
  if (phase_ != Phase::kFinished) return;
  phase_ = Phase::kSent;  // a second OnSent for the same payload is ignored
  PacketRecord& r = records_[packet_sequence % kPacketRecords];
  r.valid = true;
  r.sequence = packet_sequence;
  r.counter = counter_;
  max_packet_ids_ = std::max(max_packet_ids_, pending_ids_.size());
  if (r.ids.capacity() < max_packet_ids_) r.ids.reserve(max_packet_ids_);  // grows rarely
  r.ids.assign(pending_ids_.begin(), pending_ids_.end());
  for (const auto& [id, slot] : r.ids) {
    Track* track = tracks_.Find(id);
    if (track == nullptr) continue;
    Track& t = *track;
    Entry& e = t.ring[slot];
    if (!e.valid || e.counter != counter_) continue;
    e.sent = true;
    e.sent_at = now;
    if (t.newest_sent == kNoSlot ||
        static_cast<int32_t>(e.counter - t.ring[t.newest_sent].counter) > 0) {
      t.newest_sent = static_cast<int8_t>(slot);
    }
  }
}

void DeltaEncoder::OnPacketAcked(uint16_t packet_sequence) {
  PacketRecord& r = records_[packet_sequence % kPacketRecords];
  if (!r.valid || r.sequence != packet_sequence) {
    ++stats_.acks_unmatched;
    return;
  }
  r.valid = false;
  for (const auto& [id, slot] : r.ids) {
    Track* track = tracks_.Find(id);
    if (track == nullptr) {
      ++stats_.acks_unmatched;
      continue;
    }
    Track& t = *track;
    Entry& e = t.ring[slot];
    if (!e.valid || e.counter != r.counter) continue;  // overwritten since: too old to matter
    e.acked = true;
    if (t.newest_acked == kNoSlot || static_cast<int32_t>(e.counter - t.acked_counter) > 0) {
      t.newest_acked = static_cast<int8_t>(slot);
      t.acked_counter = e.counter;
      t.acked.q = e.q;
      t.acked.has_float = e.has_float;
      t.acked.position = e.position;
      t.acked.rotation = e.rotation;
    }
  }
}

void DeltaEncoder::Forget(uint32_t id) { tracks_.Erase(id); }

DeltaEncoder::UpdateNeed DeltaEncoder::Need(uint32_t id, const EntityState& truth,
                                            float pos_threshold_m, float rot_threshold_deg,
                                            double now, double resend_after_s) const {
  const Track* track = tracks_.Find(id);
  if (track == nullptr) return UpdateNeed::kSend;
  const Track& t = *track;
  // angle(a, b) <= threshold  <=>  |dot(a, b)| >= cos(threshold / 2).
  const double pos2 = static_cast<double>(pos_threshold_m) * pos_threshold_m;
  if (rot_threshold_deg != min_dot_for_deg_) {  // the relay passes the same threshold each call
    min_dot_for_deg_ = rot_threshold_deg;
    min_dot_ = std::cos(static_cast<double>(rot_threshold_deg) * (std::numbers::pi / 360.0));
  }
  WithinThresholds within(params_, truth, pos2, min_dot_, lattice_reach2_, lattice_min_dot_);
  if (t.newest_acked != kNoSlot && within(t.acked)) {
    return UpdateNeed::kAckedWithin;
  }
  if (t.newest_sent != kNoSlot) {
    const Entry& newest = t.ring[t.newest_sent];
    if (!newest.acked && now - newest.sent_at < resend_after_s && within(newest)) {
      return UpdateNeed::kInFlightWithin;
    }
  }
  return UpdateNeed::kSend;
}

StreamNeed DeltaStateStream::Want(const StreamEntity& e, double now, double resend_after_s,
                                  uint8_t*) {
  return ToStreamNeed(codec_.Need(e.id, *e.state, thresholds_.position_m,
                                  thresholds_.rotation_deg, now, resend_after_s));
}

bool DeltaStateStream::Add(const StreamEntity& e, uint8_t) {
  return codec_.Add(*e.state, e.prepared);  // the room quantised the state once for all
}

// ================================ Decoder ================================

DeltaStreamDecoder::DeltaStreamDecoder(const Layout& layout, const QuantizationParams& params,
                                       size_t max_entities)
    : layout_(layout), params_(params), max_entities_(max_entities) {}

DeltaDecoder::DeltaDecoder(const QuantizationParams& params, size_t max_entities)
    : DeltaStreamDecoder({kDeltaStateFormat, kDeltaHeaderSize, 5, 2, 7,
                          "malformed format-2 state payload"},
                         params, max_entities) {}

void DeltaStreamDecoder::Forget(uint32_t id) { tracks_.erase(id); }

const DeltaStreamDecoder::Entry* DeltaStreamDecoder::Resolve(Staged& s) {
  auto it = tracks_.find(s.id);
  if (it == tracks_.end()) {
    s.unresolved = Unresolved::kUnknownEntity;
    return nullptr;
  }
  s.track = &it->second;
  const Entry* base = nullptr;
  int64_t lo = INT64_MAX, hi = INT64_MIN;
  for (const Entry& e : it->second.ring) {
    if (!e.valid) continue;
    if (e.version == s.reference) base = &e;
    lo = std::min(lo, e.version);
    hi = std::max(hi, e.version);
  }
  if (base == nullptr) {
    s.unresolved = lo == INT64_MAX       ? Unresolved::kUnknownEntity
                   : s.reference < lo    ? Unresolved::kStale
                   : s.reference > hi    ? Unresolved::kFuture
                                         : Unresolved::kMissing;
  }
  return base;
}

Status DeltaStreamDecoder::Decode(std::span<const uint8_t> payload, StateBatch* out) {
  const Layout& L = layout_;
  auto fail = [&]() {
    ++stats_.malformed;
    return Status::Malformed(L.malformed);
  };
  if (payload.size() < L.header_size + 1 || payload[0] != L.format) return fail();
  const uint32_t time_ms = LoadU32LE(payload.data() + 1);
  int k[2];
  bool mask[2];
  int order[2];
  if (!UnpackParams(LoadU16LE(payload.data() + L.params_offset), k, mask, order)) return fail();
  uint32_t count = 0;
  const size_t n = GetVarint32(payload.subspan(L.header_size), &count);
  if (n == 0 || count == 0) return fail();
  const std::span<const uint8_t> stream = payload.subspan(L.header_size + n);
  if (count > stream.size() * 8 / 2) return fail();  // every record takes >= 2 bits

  // The wire carries the version's low bytes; it is extended to the value nearest the highest
  // version seen (the first payload's lands well above 0, so references stay positive).
  int64_t version;
  if (L.version_bytes == 2) {
    const uint16_t v16 = LoadU16LE(payload.data() + L.version_offset);
    version = have_version_ ? highest_version_ + static_cast<int16_t>(
                                                     v16 - static_cast<uint16_t>(highest_version_))
                            : (int64_t{1} << 20) + v16;
  } else {
    const uint32_t v32 = LoadU32LE(payload.data() + L.version_offset);
    version = have_version_ ? highest_version_ + static_cast<int32_t>(
                                                     v32 - static_cast<uint32_t>(highest_version_))
                            : (int64_t{1} << 33) + v32;
  }

  BitReader r(stream);
  staged_.clear();
  uint32_t prev_id = 0;
  uint32_t prev_distance = 1;
  for (uint32_t i = 0; i < count; ++i) {
    Staged s;
    RecordFields f;
    if (!ReadRecord(r, params_, k, mask, i, &prev_id, &prev_distance, &f)) return fail();
    s.id = f.id;
    if (f.keyframe) {
      s.keyframe = true;
      s.q = f.q;
      s.hist = ExtendHistory(nullptr, MakeSample(params_, s.q, time_ms));
    } else {
      s.reference = version - f.distance;
      const Entry* base = Resolve(s);
      if (base != nullptr) {
        if (!ReconstructDelta(params_, base->hist, order, time_ms, f, &s.q)) return fail();
        s.hist = ExtendHistory(&base->hist, MakeSample(params_, s.q, time_ms));
      }
    }
    staged_.push_back(s);
  }
  // The stream must end here: only zero padding up to the byte boundary.
  const size_t rest = r.remaining_bits();
  uint64_t pad = 0;
  if (rest >= 8 || !r.ReadBits(static_cast<int>(rest), &pad) || pad != 0) return fail();
  Commit(version, time_ms, out);
  return Status::Ok();
}

void DeltaStreamDecoder::Commit(int64_t version, uint32_t time_ms, StateBatch* out) {
  if (!have_version_ || version > highest_version_) highest_version_ = version;
  have_version_ = true;
  ++stats_.payloads;
  out->time_ms = time_ms;
  last_references_.clear();
  for (const Staged& s : staged_) {
    if (s.unresolved != Unresolved::kNone) {
      ++stats_.unresolved_references;
      switch (s.unresolved) {
        case Unresolved::kUnknownEntity: ++stats_.unknown_entity; break;
        case Unresolved::kStale: ++stats_.stale_references; break;
        case Unresolved::kFuture: ++stats_.future_references; break;
        default: ++stats_.missing_references; break;
      }
      continue;
    }
    Track* track = s.track;  // unordered_map nodes stay put while others are inserted
    if (track == nullptr) {
      auto it = tracks_.find(s.id);
      if (it == tracks_.end()) {
        if (tracks_.size() >= max_entities_) {
          ++stats_.capacity_dropped;
          continue;
        }
        it = tracks_.try_emplace(s.id).first;
      }
      track = &it->second;
    }
    if (s.keyframe) ++stats_.keyframes;
    last_references_.push_back({s.id, version, s.keyframe ? -1 : s.reference});
    // Keep the kDeltaBaselineWindow highest versions; output what is newer.
    StoreVersion(track->ring, &Entry::version, version, s.hist);
    if (OutputIfNewer(params_, s.id, s.q, version, &track->newest_output, out)) {
      ++stats_.entities;
    } else {
      ++stats_.stale_skipped;
    }
  }
}

}  // namespace edgephys
