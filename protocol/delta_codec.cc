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
constexpr int64_t kMaxGapMs = 2048;
constexpr int64_t kMaxStep = int64_t{1} << 24;
constexpr int kMaxK = 7;
// The adaptive parameters' statistics are gathered on one delta record in this many (they
// only rank the candidate orders and k; sampling cuts most of the encoder's cost).
constexpr uint64_t kStatsSampleEvery = 4;
// Format 14: the Exp-Golomb parameter of a record time's offset - 1 (ms): 5 bits up to 16 ms.
constexpr int kRecordTimeK = 4;

}  // namespace

namespace delta_internal {

// ---- Prediction (identical at both ends; integer arithmetic only) ----

namespace {
int64_t DivRound(int64_t n, int64_t d) {  // d > 0; halves away from zero
  return n >= 0 ? (n + d / 2) / d : -((-n + d / 2) / d);
}
}  // namespace

Timing MakeTiming(const History& hist, int order, uint32_t time_ms) {
  Timing t;
  t.order = std::min(order, hist.depth - 1);
  t.h = static_cast<int32_t>(time_ms - hist.s[0].time_ms);
  if (t.order >= 1) t.h2 = static_cast<int32_t>(hist.s[0].time_ms - hist.s[1].time_ms);
  if (t.order >= 2) t.h1 = static_cast<int32_t>(hist.s[1].time_ms - hist.s[2].time_ms);
  if (t.h < 0 || t.h > kMaxGapMs) t.order = 0;
  if (t.order >= 1 && (t.h2 < 1 || t.h2 > kMaxGapMs)) t.order = 0;
  if (t.order >= 2 && (t.h1 < 1 || t.h1 > kMaxGapMs)) t.order = 1;
  return t;
}

namespace {
// Newton-form polynomial extrapolation through (t2,p2), (t1,p1), (t0,p0) to t0 + h.
int64_t Extrapolate(int64_t p0, int64_t p1, int64_t p2, const Timing& t) {
  if (t.order == 0) return p0;
  const int64_t d2 = p0 - p1;
  if (d2 > kMaxStep || d2 < -kMaxStep) return p0;
  if (t.order == 1) return p0 + DivRound(t.h * d2, t.h2);
  const int64_t d1 = p1 - p2;
  if (d1 > kMaxStep || d1 < -kMaxStep) return p0 + DivRound(t.h * d2, t.h2);
  const int64_t num =
      t.h * d2 * t.h1 * (t.h1 + t.h2) + t.h * (t.h + t.h2) * (d2 * t.h1 - d1 * t.h2);
  const int64_t den = t.h1 * t.h2 * (t.h1 + t.h2);
  return p0 + DivRound(num, den);
}
}  // namespace

void PredictPosition(const QuantizationParams& p, const History& hist, const Timing& t,
                     Prediction* out) {
  for (int a = 0; a < 3; ++a) {
    int64_t v = Extrapolate(hist.s[0].pos[a], hist.s[1].pos[a], hist.s[2].pos[a], t);
    v = std::clamp<int64_t>(v, 0, p.max_index[a]);
    out->pos[a] = static_cast<uint32_t>(v);
  }
}

void PredictRotation(const QuantizationParams& p, const History& hist, const Timing& t,
                     Prediction* out) {
  // Align the older samples' signs with the newest (q and -q are the same rotation).
  std::array<int64_t, 4> r[3];
  for (int i = 0; i < 3; ++i) {
    for (int c = 0; c < 4; ++c) r[i][c] = hist.s[i].rot[c];
  }
  for (int i = 1; i < 3; ++i) {
    int64_t dot = 0;
    for (int c = 0; c < 4; ++c) dot += r[0][c] * r[i][c];
    if (dot < 0) {
      for (int c = 0; c < 4; ++c) r[i][c] = -r[i][c];
    }
  }
  const int64_t lim = 4 * static_cast<int64_t>(p.rotation_max);
  int largest = 0;
  for (int c = 0; c < 4; ++c) {
    out->rot[c] = std::clamp<int64_t>(Extrapolate(r[0][c], r[1][c], r[2][c], t), -lim, lim);
    if (std::llabs(out->rot[c]) > std::llabs(out->rot[largest])) largest = c;
  }
  out->largest = largest;
}

// The predicted smallest-three components for dropped index `largest`.
std::array<int32_t, 3> PredictedComponents(const QuantizationParams& p, const Prediction& pr,
                                           int largest) {
  const int64_t sign = pr.rot[largest] < 0 ? -1 : 1;
  std::array<int32_t, 3> c{};
  int k = 0;
  for (int i = 0; i < 4; ++i) {
    if (i == largest) continue;
    c[k++] = static_cast<int32_t>(
        std::clamp<int64_t>(sign * pr.rot[i], -p.rotation_max, p.rotation_max));
  }
  return c;
}

Sample MakeSample(const QuantizedState& q, const std::array<int32_t, 4>& rot4, uint32_t time_ms) {
  Sample s;
  for (int a = 0; a < 3; ++a) s.pos[a] = static_cast<int32_t>(q.position[a]);
  s.rot = rot4;
  s.time_ms = time_ms;
  return s;
}

Sample MakeSample(const QuantizationParams& p, const QuantizedState& q, uint32_t time_ms) {
  return MakeSample(q, RotationToInt4(p, q.rotation), time_ms);
}

bool SameLattice(const PreparedState& s, const QuantizationParams& p) {
  return s.step == p.step && s.rotation_max == p.rotation_max && s.origin[0] == p.origin[0] &&
         s.origin[1] == p.origin[1] && s.origin[2] == p.origin[2];
}

History ExtendHistory(const History* base, const Sample& s) {
  History h;
  h.s[0] = s;
  if (base == nullptr) {
    h.s[1] = h.s[2] = s;
    h.depth = 1;
  } else {
    h.s[1] = base->s[0];
    h.s[2] = base->s[1];
    h.depth = static_cast<uint8_t>(std::min(base->depth + 1, 3));
  }
  return h;
}

uint16_t PackParams(const int k[2], const bool mask[2], const int order[2]) {
  return static_cast<uint16_t>(k[0] | (k[1] << 3) | (mask[0] << 6) | (mask[1] << 7) |
                               (order[0] << 8) | (order[1] << 10));
}

bool UnpackParams(uint16_t v, int k[2], bool mask[2], int order[2]) {
  k[0] = v & 7;
  k[1] = (v >> 3) & 7;
  mask[0] = (v >> 6) & 1;
  mask[1] = (v >> 7) & 1;
  order[0] = (v >> 8) & 3;
  order[1] = (v >> 10) & 3;
  return order[0] <= 2 && order[1] <= 2 && (v >> 12) == 0;
}

bool ReadRecord(BitReader& r, const QuantizationParams& p, const int k[2], const bool mask[2],
                uint32_t i, uint32_t* prev_id, uint32_t* prev_distance, RecordFields* f,
                bool previous_symbol) {
  uint32_t v;
  if (!r.ReadExpGolomb(0, &v)) return false;
  if (i == 0) {
    f->id = v;
  } else {
    if (v >= UINT32_MAX - *prev_id) return false;
    f->id = *prev_id + 1 + v;
  }
  *prev_id = f->id;
  uint32_t sym;
  if (!r.ReadExpGolomb(0, &sym)) return false;
  const int32_t m = p.rotation_max;
  if (sym == 1) {  // keyframe
    f->keyframe = true;
    for (int a = 0; a < 3; ++a) {
      uint64_t x;
      if (!r.ReadBits(p.position_bits[a], &x) || x > p.max_index[a]) return false;
      f->q.position[a] = static_cast<uint32_t>(x);
    }
    uint64_t li;
    if (!r.ReadBits(2, &li)) return false;
    f->q.rotation.largest = static_cast<uint8_t>(li);
    for (int c = 0; c < 3; ++c) {
      uint64_t x;
      if (!r.ReadBits(p.rotation_bits, &x) || x > 2 * static_cast<uint64_t>(m)) return false;
      f->q.rotation.c[c] = static_cast<int32_t>(x) - m;
    }
    return true;
  }
  if (previous_symbol && sym == 0) {
    f->previous = true;  // resolved by the decoder: the newest version held below this payload
  } else {
    const int64_t distance =
        previous_symbol ? static_cast<int64_t>(*prev_distance) + UnZigZag(sym - 2)
        : sym == 0      ? *prev_distance
                        : static_cast<int64_t>(*prev_distance) + UnZigZag(sym - 1);
    if (distance < 1 || distance > kMaxReferenceDistance) return false;
    *prev_distance = static_cast<uint32_t>(distance);
    f->distance = distance;
  }
  bool pos_coded = true, rot_coded = true;
  if (mask[0] && !r.ReadBit(&pos_coded)) return false;
  if (mask[1] && !r.ReadBit(&rot_coded)) return false;
  if (pos_coded) {
    for (int32_t& x : f->pos_res) {
      if (!r.ReadSigned(k[0], &x)) return false;
    }
  }
  if (rot_coded) {
    if (!r.ReadBit(&f->same_index)) return false;
    if (!f->same_index && !r.ReadBits(2, &f->index)) return false;
    for (int32_t& x : f->rot_res) {
      if (!r.ReadSigned(k[1], &x)) return false;
    }
  }
  return true;
}

bool ReconstructDelta(const QuantizationParams& p, const History& h, const int order[2],
                      uint32_t time_ms, const RecordFields& f, QuantizedState* q) {
  Prediction pp, pr;
  PredictPosition(p, h, MakeTiming(h, order[0], time_ms), &pp);
  PredictRotation(p, h, MakeTiming(h, order[1], time_ms), &pr);
  for (int a = 0; a < 3; ++a) {
    const int64_t x = static_cast<int64_t>(pp.pos[a]) + f.pos_res[a];
    if (x < 0 || x > p.max_index[a]) return false;
    q->position[a] = static_cast<uint32_t>(x);
  }
  const int li = f.same_index ? pr.largest : static_cast<int>(f.index);
  const std::array<int32_t, 3> pc = PredictedComponents(p, pr, li);
  q->rotation.largest = static_cast<uint8_t>(li);
  const int32_t m = p.rotation_max;
  for (int c = 0; c < 3; ++c) {
    const int64_t x = static_cast<int64_t>(pc[c]) + f.rot_res[c];
    if (x < -m || x > m) return false;
    q->rotation.c[c] = static_cast<int32_t>(x);
  }
  return true;
}

}  // namespace delta_internal

using namespace delta_internal;  // NOLINT

// ================================ Velocities (format 12) ================================

namespace {
// Bits of one velocity group (3 components) at k.
int VelocityGroupBits(const std::array<int32_t, 3>& c, int k) {
  int bits = 0;
  for (int32_t x : c) bits += ExpGolombBits(ZigZag(x), k);
  return bits;
}
constexpr int VelocityK(int index) { return 2 * index + 1; }
constexpr uint16_t kVelocityParamsShift = 12;
}  // namespace

// ================================ Encoder ================================

DeltaEncoder::DeltaEncoder(const QuantizationParams& params, const DeltaEncoderOptions& options)
    : params_(params), options_(options), records_(kPacketRecords) {
  if (options_.velocities) {  // format 12 has no such symbol, nor record times
    options_.previous_reference = false;
    options_.record_times = false;
  }
  if (options_.record_times) options_.previous_reference = true;  // format 14 extends 13
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
  for (int g = 0; g < 2 && options_.velocities; ++g) {
    double best = std::numeric_limits<double>::infinity();
    for (int i = 0; i < 4; ++i) {
      if (velocity_costs_[g][i] > 0 && velocity_costs_[g][i] < best) {
        best = velocity_costs_[g][i];
        velocity_k_[g] = i;
      }
    }
  }
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
  for (auto& g : packet_velocity_costs_) std::fill(std::begin(g), std::end(g), 0.0);
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

bool DeltaEncoder::AddAt(const EntityState& truth, const PreparedState* prepared,
                         uint32_t record_time_ms) {
  if (!options_.record_times || time_ms_ - record_time_ms > kMaxRecordAgeMs) return false;
  return AddRecord(truth, prepared, nullptr, record_time_ms);
}

bool DeltaEncoder::AddRecord(const EntityState& truth, const PreparedState* prepared,
                             const EntityVelocity* velocity, uint32_t record_time_ms) {
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
  bool previous = false;  // format 13: coded as "the previous version"
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
    for (int a = 0; a < 3; ++a) ok = ok && w.WriteBits(q.position[a], params_.position_bits[a]);
    ok = ok && w.WriteBits(q.rotation.largest, 2);
    for (int c = 0; c < 3; ++c) {
      ok = ok && w.WriteBits(static_cast<uint32_t>(q.rotation.c[c] + params_.rotation_max),
                             params_.rotation_bits);
    }
  } else {
    distance = counter_ - base_entry->counter;
    uint32_t sym;
    if (options_.previous_reference) {
      // Format 13: "the previous version" when no newer version of the entity was put in a
      // payload since the reference (then the decoder's newest below this payload is it).
      previous = &track.ring[(track.next + kDeltaBaselineWindow - 1) % kDeltaBaselineWindow] ==
                 base_entry;
      sym = previous ? 0
                     : ZigZag(static_cast<int32_t>(distance) - static_cast<int32_t>(prev_distance_)) + 2;
    } else {
      sym = distance == prev_distance_
                ? 0
                : ZigZag(static_cast<int32_t>(distance) - static_cast<int32_t>(prev_distance_)) + 1;
    }
    ok = ok && w.WriteExpGolomb(sym, 0);
    at_ref = w.bit_position();

    // Residuals for every order (statistics for the adaptive parameters) on one delta record
    // in kStatsSampleEvery; otherwise only for the orders in use. Code the chosen one.
    const int po = order_[0], ro = order_[1];
    sample = records_added_++ % kStatsSampleEvery == 0;
    std::array<int32_t, 3> pos_res[3];
    std::array<int32_t, 3> rot_res[3];
    bool pos_zero[3], rot_zero[3], rot_same[3];
    for (int o = 0; o < 3; ++o) {
      if (!sample && o != po) continue;
      Prediction pp;
      PredictPosition(params_, base_hist, MakeTiming(base_hist, o, record_time_ms), &pp);
      pos_zero[o] = true;
      for (int a = 0; a < 3; ++a) {
        pos_res[o][a] = static_cast<int32_t>(static_cast<int64_t>(q.position[a]) - pp.pos[a]);
        pos_zero[o] = pos_zero[o] && pos_res[o][a] == 0;
      }
    }
    for (int o = 0; o < 3; ++o) {
      if (!sample && o != ro) continue;
      Prediction pr;
      PredictRotation(params_, base_hist, MakeTiming(base_hist, o, record_time_ms), &pr);
      const int li = q.rotation.largest;
      const std::array<int32_t, 3> pc = PredictedComponents(params_, pr, li);
      rot_same[o] = li == pr.largest;
      rot_zero[o] = rot_same[o];
      for (int c = 0; c < 3; ++c) {
        rot_res[o][c] = q.rotation.c[c] - pc[c];
        rot_zero[o] = rot_zero[o] && rot_res[o][c] == 0;
      }
    }
    if (sample) {
      for (int o = 0; o < 3; ++o) {
        for (int k = 0; k <= kMaxK; ++k) {
          double pos_bits = 0, rot_bits = rot_same[o] ? 1 : 3;
          for (int a = 0; a < 3; ++a) {
            pos_bits += ExpGolombBits(ZigZag(pos_res[o][a]), k);
            rot_bits += ExpGolombBits(ZigZag(rot_res[o][a]), k);
          }
          add_full[0][o][k] = pos_bits;
          add_full[1][o][k] = rot_bits;
          add_masked[0][o][k] = 1 + (pos_zero[o] ? 0 : pos_bits);
          add_masked[1][o][k] = 1 + (rot_zero[o] ? 0 : rot_bits);
        }
      }
    }
    // With a reduced history the effective order is lower, but the residual is the same.
    const bool pos_coded = !mask_[0] || !pos_zero[po];
    const bool rot_coded = !mask_[1] || !rot_zero[ro];
    if (mask_[0]) ok = ok && w.WriteBit(pos_coded);
    if (mask_[1]) ok = ok && w.WriteBit(rot_coded);
    at_mask = w.bit_position();
    if (pos_coded) {
      for (int a = 0; a < 3; ++a) {
        ok = ok && w.WriteSigned(pos_res[po][a], k_[0]);
        eg_bits += ExpGolombBits(ZigZag(pos_res[po][a]), k_[0]);
        max_zz[0] = std::max(max_zz[0], ZigZag(pos_res[po][a]));
      }
      n_residuals[0] = 3;
    }
    at_pos = w.bit_position();
    if (rot_coded) {
      const bool same = rot_same[ro];
      ok = ok && w.WriteBit(same);
      if (!same) ok = ok && w.WriteBits(q.rotation.largest, 2);
      for (int c = 0; c < 3; ++c) {
        ok = ok && w.WriteSigned(rot_res[ro][c], k_[1]);
        eg_bits += ExpGolombBits(ZigZag(rot_res[ro][c]), k_[1]);
        max_zz[1] = std::max(max_zz[1], ZigZag(rot_res[ro][c]));
      }
      n_residuals[1] = 3;
    }
  }
  const size_t at_rot = w.bit_position();
  // Format 14: the record's time, back from the payload's.
  if (options_.record_times) {
    const uint32_t offset = time_ms_ - record_time_ms;  // <= kMaxRecordAgeMs (AddAt)
    ok = ok && w.WriteBit(offset != 0);
    if (offset != 0) ok = ok && w.WriteExpGolomb(offset - 1, kRecordTimeK);
  }
  const size_t at_time = w.bit_position();
  // Format 12: the velocity, absolute.
  QuantizedVelocity qv;
  double add_velocity[2][4] = {};
  if (options_.velocities) {
    if (velocity != nullptr) qv = QuantizeVelocity(*velocity);
    const bool moving = qv.moving();
    ok = ok && w.WriteBit(moving);
    if (moving) {
      for (int a = 0; a < 3; ++a) ok = ok && w.WriteSigned(qv.linear[a], VelocityK(velocity_k_[0]));
      for (int a = 0; a < 3; ++a) ok = ok && w.WriteSigned(qv.angular[a], VelocityK(velocity_k_[1]));
      for (int i = 0; i < 4; ++i) {
        add_velocity[0][i] = VelocityGroupBits(qv.linear, VelocityK(i));
        add_velocity[1][i] = VelocityGroupBits(qv.angular, VelocityK(i));
      }
    }
  }
  if (!ok) {
    writer_.Rewind(mark);
    return false;
  }
  for (int g = 0; g < 2; ++g) {
    for (int i = 0; i < 4; ++i) packet_velocity_costs_[g][i] += add_velocity[g][i];
  }

  // Committed: record the state as sent-in-this-payload.
  last_bits_[kRecordPartId] = static_cast<uint32_t>(at_id - mark);
  last_bits_[kRecordPartReference] =
      static_cast<uint32_t>(at_ref - at_id) + static_cast<uint32_t>(at_time - at_rot);
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
    if (!previous) prev_distance_ = distance;
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
  e.velocity = qv;
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
  p[0] = options_.velocities            ? kVelocityDeltaStateFormat
         : options_.record_times       ? kTimedDeltaStateFormat
         : options_.previous_reference ? kPreviousDeltaStateFormat
                                       : kDeltaStateFormat;
  StoreU32LE(p + 1, time_ms_);
  StoreU16LE(p + 5, static_cast<uint16_t>(counter_));
  uint16_t params = PackParams(k_, mask_, order_);
  if (options_.velocities) {
    params |= static_cast<uint16_t>((velocity_k_[0] | (velocity_k_[1] << 2)) << kVelocityParamsShift);
    for (int g = 0; g < 2; ++g) {
      for (int i = 0; i < 4; ++i) {
        velocity_costs_[g][i] = 0.5 * velocity_costs_[g][i] + packet_velocity_costs_[g][i];
      }
    }
  }
  StoreU16LE(p + 7, params);
  uint8_t cnt[5];
  const size_t cnt_size = PutVarint32(static_cast<uint32_t>(count_), cnt);
  std::memcpy(p + kDeltaHeaderSize, cnt, cnt_size);
  const size_t body = writer_.byte_size();
  const size_t dst = kDeltaHeaderSize + cnt_size;
  std::memmove(p + dst, p + kStreamStart, body);

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
  return dst + body;
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
      t.acked.velocity = e.velocity;
      t.acked.time_ms = e.hist.s[0].time_ms;
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

DeltaEncoder::UpdateNeed DeltaEncoder::NeedExtrapolated(uint32_t id, const EntityState& truth,
                                                        float pos_threshold_m,
                                                        float rot_threshold_deg, double now,
                                                        double resend_after_s,
                                                        uint32_t time_ms) const {
  const Track* track = tracks_.Find(id);
  if (track == nullptr) return UpdateNeed::kSend;
  const Track& t = *track;
  auto moving = [&](const auto& held) { return options_.velocities && held.velocity.moving(); };
  const bool acked_moving = t.newest_acked != kNoSlot && moving(t.acked);
  const Entry* in_flight = nullptr;
  if (t.newest_sent != kNoSlot) {
    const Entry& newest = t.ring[t.newest_sent];
    if (!newest.acked && now - newest.sent_at < resend_after_s) in_flight = &newest;
  }
  const bool flight_moving = in_flight != nullptr && moving(*in_flight);
  if (!acked_moving && !flight_moving) {
    return Need(id, truth, pos_threshold_m, rot_threshold_deg, now, resend_after_s);
  }
  // A moving held state, extrapolated to `time_ms` the way a receiver shows it.
  const double pos2 = static_cast<double>(pos_threshold_m) * pos_threshold_m;
  const double min_dot = std::cos(static_cast<double>(rot_threshold_deg) * (std::numbers::pi / 360.0));
  auto shown_within = [&](const auto& held, uint32_t held_time_ms) {
    if (!held.has_float) {
      held.position = DequantizePosition(params_, held.q.position);
      held.rotation = DequantizeRotation(params_, held.q.rotation);
      held.has_float = true;
    }
    EntityState base;
    base.position = held.position;
    base.rotation = held.rotation;
    const double dt = static_cast<int32_t>(time_ms - held_time_ms) / 1000.0;
    const EntityState shown = ExtrapolateState(base, DequantizeVelocity(held.velocity), dt);
    const double dx = static_cast<double>(shown.position.x) - truth.position.x;
    const double dy = static_cast<double>(shown.position.y) - truth.position.y;
    const double dz = static_cast<double>(shown.position.z) - truth.position.z;
    if (dx * dx + dy * dy + dz * dz > pos2) return false;
    const Quatf& a = shown.rotation;
    const Quatf& b = truth.rotation;
    const double dot = static_cast<double>(a.x) * b.x + static_cast<double>(a.y) * b.y +
                       static_cast<double>(a.z) * b.z + static_cast<double>(a.w) * b.w;
    return std::fabs(dot) >= min_dot;
  };
  if (t.newest_acked != kNoSlot) {
    if (acked_moving) {
      if (shown_within(t.acked, t.acked.time_ms)) return UpdateNeed::kExtrapolatedWithin;
    } else {
      WithinThresholds within(params_, truth, pos2, min_dot, lattice_reach2_, lattice_min_dot_);
      if (within(t.acked)) return UpdateNeed::kAckedWithin;
    }
  }
  if (in_flight != nullptr) {
    if (flight_moving) {
      if (shown_within(*in_flight, in_flight->hist.s[0].time_ms)) return UpdateNeed::kInFlightWithin;
    } else {
      WithinThresholds within(params_, truth, pos2, min_dot, lattice_reach2_, lattice_min_dot_);
      if (within(*in_flight)) return UpdateNeed::kInFlightWithin;
    }
  }
  return UpdateNeed::kSend;
}

bool DeltaEncoder::NewestSent(uint32_t id, EntityState* state, EntityVelocity* velocity,
                              uint32_t* time_ms) const {
  const Track* track = tracks_.Find(id);
  if (track == nullptr || track->newest_sent == kNoSlot) return false;
  const Entry& e = track->ring[track->newest_sent];
  if (!e.valid || !e.sent) return false;
  if (!e.has_float) {
    e.position = DequantizePosition(params_, e.q.position);
    e.rotation = DequantizeRotation(params_, e.q.rotation);
    e.has_float = true;
  }
  state->entity_id = id;
  state->position = e.position;
  state->rotation = e.rotation;
  *velocity = DequantizeVelocity(e.velocity);
  *time_ms = e.hist.s[0].time_ms;
  return true;
}

// ================================ Decoder ================================

DeltaDecoder::DeltaDecoder(const QuantizationParams& params, size_t max_entities)
    : params_(params), max_entities_(max_entities) {}

void DeltaDecoder::Forget(uint32_t id) { tracks_.erase(id); }

Status DeltaDecoder::Decode(std::span<const uint8_t> payload, StateBatch* out) {
  const Status malformed = Status::Malformed("malformed format-2/12/13/14 state payload");
  auto fail = [&]() {
    ++stats_.malformed;
    return malformed;
  };
  if (payload.size() < kDeltaHeaderSize + 1 ||
      (payload[0] != kDeltaStateFormat && payload[0] != kVelocityDeltaStateFormat &&
       payload[0] != kPreviousDeltaStateFormat && payload[0] != kTimedDeltaStateFormat)) {
    return fail();
  }
  const bool velocities = payload[0] == kVelocityDeltaStateFormat;
  const bool record_times = payload[0] == kTimedDeltaStateFormat;
  const bool previous_symbol = payload[0] == kPreviousDeltaStateFormat || record_times;
  const uint32_t time_ms = LoadU32LE(payload.data() + 1);
  const uint16_t counter16 = LoadU16LE(payload.data() + 5);
  int k[2];
  bool mask[2];
  int order[2];
  uint16_t params = LoadU16LE(payload.data() + 7);
  int velocity_k[2] = {0, 0};
  if (velocities) {
    velocity_k[0] = VelocityK((params >> kVelocityParamsShift) & 3);
    velocity_k[1] = VelocityK((params >> (kVelocityParamsShift + 2)) & 3);
    params &= (uint16_t{1} << kVelocityParamsShift) - 1;
  }
  if (!UnpackParams(params, k, mask, order)) return fail();
  uint32_t count = 0;
  const size_t n = GetVarint32(payload.subspan(kDeltaHeaderSize), &count);
  if (n == 0 || count == 0) return fail();
  const std::span<const uint8_t> stream = payload.subspan(kDeltaHeaderSize + n);
  if (count > stream.size() * 8 / 2) return fail();  // every record takes >= 2 bits

  const int64_t counter =
      have_counter_ ? highest_counter_ +
                          static_cast<int16_t>(counter16 - static_cast<uint16_t>(highest_counter_))
                    : (int64_t{1} << 20) + counter16;

  BitReader r(stream);
  staged_.clear();
  uint32_t prev_id = 0;
  uint32_t prev_distance = 1;
  for (uint32_t i = 0; i < count; ++i) {
    Staged s;
    RecordFields f;
    if (!ReadRecord(r, params_, k, mask, i, &prev_id, &prev_distance, &f, previous_symbol)) {
      return fail();
    }
    s.id = f.id;
    s.time_ms = time_ms;
    if (record_times) {  // format 14: the record's own time
      bool own = false;
      if (!r.ReadBit(&own)) return fail();
      uint32_t back = 0;
      if (own && !r.ReadExpGolomb(kRecordTimeK, &back)) return fail();
      if (own && back >= kMaxRecordAgeMs) {
        ++stats_.record_times_refused;
        return fail();
      }
      s.time_ms = time_ms - (own ? back + 1 : 0);
    }
    if (velocities) {
      bool moving = false;
      if (!r.ReadBit(&moving)) return fail();
      for (int a = 0; a < 6 && moving; ++a) {
        int32_t x = 0;
        if (!r.ReadSigned(velocity_k[a / 3], &x) || x < -kMaxVelocityIndex || x > kMaxVelocityIndex) {
          return fail();
        }
        (a < 3 ? s.velocity.linear[a] : s.velocity.angular[a - 3]) = x;
      }
    }
    if (f.keyframe) {
      s.keyframe = true;
      s.q = f.q;
      s.resolved = true;
      s.hist = ExtendHistory(nullptr, MakeSample(params_, s.q, s.time_ms));
    } else {
      s.reference = f.previous ? -1 : counter - f.distance;
      // Resolve the reference: exact payload counter match (format 13's "previous": the highest
      // counter held below this payload's, at most kMaxReferenceDistance below), or the record
      // is skipped.
      const Entry* base = nullptr;
      auto it = tracks_.find(s.id);
      if (it != tracks_.end()) {
        s.track = &it->second;
        for (const Entry& e : it->second.ring) {
          if (!e.valid) continue;
          if (f.previous ? e.counter < counter && (base == nullptr || e.counter > base->counter)
                         : e.counter == s.reference) {
            base = &e;
          }
        }
        if (f.previous && base != nullptr) {
          if (counter - base->counter > kMaxReferenceDistance) base = nullptr;
          else s.reference = base->counter;
        }
      }
      if (base != nullptr) {
        if (!ReconstructDelta(params_, base->hist, order, s.time_ms, f, &s.q)) return fail();
        s.resolved = true;
        s.hist = ExtendHistory(&base->hist, MakeSample(params_, s.q, s.time_ms));
      }
    }
    staged_.push_back(s);
  }
  // The stream must end here: only zero padding up to the byte boundary.
  const size_t rest = r.remaining_bits();
  uint64_t pad = 0;
  if (rest >= 8 || !r.ReadBits(static_cast<int>(rest), &pad) || pad != 0) return fail();

  // Commit.
  if (!have_counter_ || counter > highest_counter_) highest_counter_ = counter;
  have_counter_ = true;
  ++stats_.payloads;
  out->time_ms = time_ms;
  last_references_.clear();
  if (velocities) out->velocities.resize(out->states.size());
  if (record_times) out->times_ms.resize(out->states.size(), time_ms);
  for (const Staged& s : staged_) {
    if (!s.resolved) {
      ++stats_.unresolved_references;
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
    Track& t = *track;
    if (s.keyframe) ++stats_.keyframes;
    last_references_.push_back({s.id, counter, s.keyframe ? -1 : s.reference});
    // Keep the kDeltaBaselineWindow highest counters; output what is newer.
    StoreVersion(t.ring, &Entry::counter, counter, s.hist);
    if (OutputIfNewer(params_, s.id, s.q, counter, &t.newest_output, out)) {
      ++stats_.entities;
      if (velocities) out->velocities.push_back(DequantizeVelocity(s.velocity));
      if (record_times) out->times_ms.push_back(s.time_ms);
    } else {
      ++stats_.stale_skipped;
    }
  }
  return Status::Ok();
}

}  // namespace edgephys
