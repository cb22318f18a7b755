// The prediction and record coding that state formats 2 and 9 share (protocol/delta_prediction.h).
#include "protocol/delta_prediction.h"

#include <algorithm>
#include <cstring>

namespace edgephys {
namespace {

constexpr int64_t kMaxGapMs = 2048;
constexpr int64_t kMaxStep = int64_t{1} << 24;

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

void ComputeResiduals(const QuantizationParams& p, const History& h, const QuantizedState& q,
                      uint32_t time_ms, const int order[2], bool all_orders, Residuals* out) {
  for (int o = 0; o < 3; ++o) {
    if (!all_orders && o != order[0]) continue;
    Prediction pp;
    PredictPosition(p, h, MakeTiming(h, o, time_ms), &pp);
    out->pos_zero[o] = true;
    for (int a = 0; a < 3; ++a) {
      out->pos[o][a] = static_cast<int32_t>(static_cast<int64_t>(q.position[a]) - pp.pos[a]);
      out->pos_zero[o] = out->pos_zero[o] && out->pos[o][a] == 0;
    }
  }
  for (int o = 0; o < 3; ++o) {
    if (!all_orders && o != order[1]) continue;
    Prediction pr;
    PredictRotation(p, h, MakeTiming(h, o, time_ms), &pr);
    const int li = q.rotation.largest;
    const std::array<int32_t, 3> pc = PredictedComponents(p, pr, li);
    out->rot_same[o] = li == pr.largest;
    out->rot_zero[o] = out->rot_same[o];
    for (int c = 0; c < 3; ++c) {
      out->rot[o][c] = q.rotation.c[c] - pc[c];
      out->rot_zero[o] = out->rot_zero[o] && out->rot[o][c] == 0;
    }
  }
}

bool WriteKeyframeState(BitWriter& w, const QuantizationParams& p, const QuantizedState& q) {
  bool ok = true;
  for (int a = 0; a < 3; ++a) ok = ok && w.WriteBits(q.position[a], p.position_bits[a]);
  ok = ok && w.WriteBits(q.rotation.largest, 2);
  for (int c = 0; c < 3; ++c) {
    ok = ok && w.WriteBits(static_cast<uint32_t>(q.rotation.c[c] + p.rotation_max), p.rotation_bits);
  }
  return ok;
}

bool WriteDeltaBody(BitWriter& w, const Residuals& r, const QuantizedState& q, const int k[2],
                    const bool mask[2], const int order[2], DeltaBodyMarks* marks) {
  // With a reduced history the effective order is lower, but the residual is the same.
  const int po = order[0], ro = order[1];
  marks->pos_coded = !mask[0] || !r.pos_zero[po];
  marks->rot_coded = !mask[1] || !r.rot_zero[ro];
  bool ok = true;
  if (mask[0]) ok = ok && w.WriteBit(marks->pos_coded);
  if (mask[1]) ok = ok && w.WriteBit(marks->rot_coded);
  marks->at_mask = w.bit_position();
  if (marks->pos_coded) {
    for (int a = 0; a < 3; ++a) ok = ok && w.WriteSigned(r.pos[po][a], k[0]);
  }
  marks->at_pos = w.bit_position();
  if (marks->rot_coded) {
    ok = ok && w.WriteBit(r.rot_same[ro]);
    if (!r.rot_same[ro]) ok = ok && w.WriteBits(q.rotation.largest, 2);
    for (int c = 0; c < 3; ++c) ok = ok && w.WriteSigned(r.rot[ro][c], k[1]);
  }
  return ok;
}

size_t PlaceRecordStream(uint8_t* payload, size_t header_size, size_t count, size_t stream_start,
                         size_t body) {
  uint8_t cnt[5];
  const size_t cnt_size = PutVarint32(static_cast<uint32_t>(count), cnt);
  std::memcpy(payload + header_size, cnt, cnt_size);
  std::memmove(payload + header_size + cnt_size, payload + stream_start, body);
  return header_size + cnt_size + body;
}

bool ReadRecord(BitReader& r, const QuantizationParams& p, const int k[2], const bool mask[2],
                uint32_t i, uint32_t* prev_id, uint32_t* prev_distance, RecordFields* f) {
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
  const int64_t distance =
      sym == 0 ? *prev_distance : static_cast<int64_t>(*prev_distance) + UnZigZag(sym - 1);
  if (distance < 1 || distance > kMaxReferenceDistance) return false;
  *prev_distance = static_cast<uint32_t>(distance);
  f->distance = distance;
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

}  // namespace edgephys
