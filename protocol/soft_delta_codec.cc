#include "protocol/soft_delta_codec.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "protocol/bit_stream.h"
#include "protocol/byte_io.h"
#include "protocol/range_coder.h"
#include "protocol/state_codec.h"

namespace edgephys {
namespace {

constexpr int kMaxLength = 30;  // residuals are < 2^31 in magnitude: Elias-gamma length <= 30
constexpr int64_t kResidualLimit = int64_t{1} << 31;
constexpr size_t kMaxRecordHeader = 6 * 5 + 1 + 2 * 5 + 3 * 5 + 5;

// Adaptive models of one record's residual stream (both sides start from the same state).
struct ResidualModel {
  RangeProb zero[3][6][3];  // [axis][context][motion]
  RangeProb sign[3][6];
  RangeProb length[3][3][3][kMaxLength];  // [axis][previous particle's bucket][motion][bit]
  RangeProb mantissa[3][kMaxLength + 1];
  ResidualModel() {
    std::fill_n(&zero[0][0][0], sizeof zero / sizeof(RangeProb), kRangeProbInit);
    std::fill_n(&sign[0][0], sizeof sign / sizeof(RangeProb), kRangeProbInit);
    std::fill_n(&length[0][0][0][0], sizeof length / sizeof(RangeProb), kRangeProbInit);
    std::fill_n(&mantissa[0][0], sizeof mantissa / sizeof(RangeProb), kRangeProbInit);
  }
};

int Bucket(int64_t v) { return v == 0 ? 0 : (v == 1 || v == -1) ? 1 : 2; }

// Context of axis `a` of a particle: the previous particle's residual on that axis, and whether
// an earlier axis of this particle was non-zero.
int Context(int64_t prev_same_axis, bool earlier_nonzero) {
  return Bucket(prev_same_axis) + (earlier_nonzero ? 3 : 0);
}

void EncodeResidual(RangeEncoder& rc, ResidualModel& m, int axis, int ctx, int mc, int64_t v) {
  rc.EncodeBit(&m.zero[axis][ctx][mc], v != 0);
  if (v == 0) return;
  rc.EncodeBit(&m.sign[axis][ctx], v < 0);
  const uint32_t mag = static_cast<uint32_t>(v < 0 ? -v : v);
  const int n = std::bit_width(mag) - 1;  // 0..30
  const int cb = ctx % 3;
  for (int i = 0; i < n; ++i) rc.EncodeBit(&m.length[axis][cb][mc][i], true);
  if (n < kMaxLength) rc.EncodeBit(&m.length[axis][cb][mc][n], false);
  if (n >= 1) {
    rc.EncodeBit(&m.mantissa[axis][n], ((mag >> (n - 1)) & 1u) != 0);
    for (int j = n - 2; j >= 0; --j) rc.EncodeDirect(((mag >> j) & 1u) != 0);
  }
}

int64_t DecodeResidual(RangeDecoder& rc, ResidualModel& m, int axis, int ctx, int mc) {
  if (!rc.DecodeBit(&m.zero[axis][ctx][mc])) return 0;
  const bool negative = rc.DecodeBit(&m.sign[axis][ctx]);
  const int cb = ctx % 3;
  int n = 0;
  while (n < kMaxLength && rc.DecodeBit(&m.length[axis][cb][mc][n])) ++n;
  uint32_t mag = 1;
  if (n >= 1) {
    mag = (mag << 1) | (rc.DecodeBit(&m.mantissa[axis][n]) ? 1u : 0u);
    for (int j = n - 2; j >= 0; --j) mag = (mag << 1) | (rc.DecodeDirect() ? 1u : 0u);
  }
  return negative ? -static_cast<int64_t>(mag) : static_cast<int64_t>(mag);
}

// Rough cost of a residual in quarter bits (for choosing a mode only).
uint64_t Cost(int64_t v) {
  if (v == 0) return 1;
  const uint64_t mag = static_cast<uint64_t>(v < 0 ? -v : v);
  return 12 + 8 * static_cast<uint64_t>(std::bit_width(mag) - 1);
}

int64_t RoundDiv(int64_t n, int64_t d) {
  return n >= 0 ? (n + d / 2) / d : -((-n + d / 2) / d);
}

int64_t ClampLattice(int64_t v) {
  return std::clamp(v, -(kSoftLatticeLimit - 1), kSoftLatticeLimit - 1);
}

bool ExtrapolationAllowed(const SoftDeltaRefs& r) {
  return r.base_dt_ms >= 1 && r.base_dt_ms <= kSoftMaxExtrapolationMs &&
         r.dt_ms <= kSoftMaxExtrapolationMs;
}

// Prediction of coordinate k (3 x particle + axis) by `predictor`.
int64_t Predict(uint8_t predictor, const SoftDeltaRefs& r, size_t k) {
  switch (predictor) {
    case kSoftBaseline: return r.base[k];
    case kSoftExtrapolate: {
      const int64_t b = r.base[k];
      const int64_t slope = b - r.base2[k];
      return ClampLattice(b + RoundDiv(slope * static_cast<int64_t>(r.dt_ms),
                                       static_cast<int64_t>(r.base_dt_ms)));
    }
    default: return 0;
  }
}

struct Choice {
  uint8_t mode = kSoftKeyframe | kSoftModeDiff;
  int32_t offset[3] = {0, 0, 0};
  uint64_t cost = std::numeric_limits<uint64_t>::max();
};

// Fills scratch->residuals with the coded residuals of `mode` for [first, first + n); false if
// one leaves the residual range.
bool Residuals(const SoftDeltaRecordInput& in, uint32_t n, uint8_t mode, const int32_t offset[3],
               std::vector<int64_t>* out) {
  out->resize(size_t{n} * 3);
  const uint8_t predictor = mode & 3;
  int64_t prev[3] = {0, 0, 0};
  for (uint32_t i = 0; i < n; ++i) {
    const size_t p = size_t{in.first} + i;
    for (int a = 0; a < 3; ++a) {
      const size_t k = p * 3 + static_cast<size_t>(a);
      const int64_t e = static_cast<int64_t>(in.q[k]) - Predict(predictor, in.refs, k) - offset[a];
      int64_t r = e;
      if (mode & kSoftModeDiff) {
        r = e - prev[a];
        prev[a] = e;
      }
      if (r <= -kResidualLimit || r >= kResidualLimit) return false;
      (*out)[size_t{i} * 3 + static_cast<size_t>(a)] = r;
    }
  }
  return true;
}

uint64_t EstimateCost(const std::vector<int64_t>& r) {
  uint64_t c = 0;
  for (int64_t v : r) c += Cost(v);
  return c;
}

// Picks the cheapest mode for [first, first + n) by estimated cost.
Choice ChooseMode(const SoftDeltaRecordInput& in, uint32_t n, std::vector<int64_t>* tmp) {
  Choice best;
  const int32_t zero[3] = {0, 0, 0};
  if (Residuals(in, n, best.mode, zero, tmp)) best.cost = EstimateCost(*tmp);
  const size_t size = in.q.size();
  for (uint8_t predictor : {kSoftBaseline, kSoftExtrapolate}) {
    if (in.refs.base.size() != size || in.refs.base_distance == 0) break;
    if (predictor == kSoftExtrapolate &&
        (in.refs.base2.size() != size || in.refs.base2_distance == 0 || !ExtrapolationAllowed(in.refs))) {
      break;
    }
    // Mean motion of the record against this predictor.
    double sum[3] = {0, 0, 0};
    for (uint32_t i = 0; i < n; ++i) {
      const size_t p = size_t{in.first} + i;
      for (size_t a = 0; a < 3; ++a) {
        sum[a] += static_cast<double>(in.q[p * 3 + a] - Predict(predictor, in.refs, p * 3 + a));
      }
    }
    int32_t offset[3];
    bool any_offset = false;
    for (int a = 0; a < 3; ++a) {
      offset[a] = static_cast<int32_t>(
          ClampLattice(static_cast<int64_t>(std::llround(sum[a] / static_cast<double>(n)))));
      any_offset |= offset[a] != 0;
    }
    for (uint8_t flags : {uint8_t{0}, kSoftModeDiff, kSoftModeOffset}) {
      if (flags == kSoftModeOffset && !any_offset) continue;
      const uint8_t mode = static_cast<uint8_t>(predictor | flags);
      const int32_t* off = (flags & kSoftModeOffset) ? offset : zero;
      if (!Residuals(in, n, mode, off, tmp)) continue;
      const uint64_t cost = EstimateCost(*tmp) + ((flags & kSoftModeOffset) ? 48 : 0);
      if (cost < best.cost) {
        best.cost = cost;
        best.mode = mode;
        std::memcpy(best.offset, off, sizeof best.offset);
      }
    }
  }
  return best;
}

// Motion context of coordinate k: how far it moved between the two baselines (0, 1, more).
int MotionContext(const SoftDeltaRefs& r, bool enabled, size_t k) {
  return enabled ? Bucket(static_cast<int64_t>(r.base[k]) - r.base2[k]) : 0;
}

// The coded size, or SIZE_MAX if it does not fit `out` (an all-zero stream codes to 0 bytes).
size_t CodeResiduals(const std::vector<int64_t>& residuals, const SoftDeltaRefs& refs,
                     bool motion, size_t first, std::span<uint8_t> out) {
  RangeEncoder rc(out);
  ResidualModel model;
  int64_t prev[3] = {0, 0, 0};
  for (size_t i = 0; i < residuals.size(); i += 3) {
    bool earlier = false;
    for (int a = 0; a < 3; ++a) {
      const int64_t v = residuals[i + static_cast<size_t>(a)];
      EncodeResidual(rc, model, a, Context(prev[a], earlier),
                     MotionContext(refs, motion, first * 3 + i + static_cast<size_t>(a)), v);
      prev[a] = v;
      earlier |= v != 0;
    }
    if (rc.overflow()) return SIZE_MAX;
  }
  const size_t size = rc.Finish();
  return rc.overflow() ? SIZE_MAX : size;
}

bool GetVarint(std::span<const uint8_t> payload, size_t* pos, uint32_t* v) {
  const size_t n = GetVarint32(payload.subspan(std::min(*pos, payload.size())), v);
  if (n == 0) return false;
  *pos += n;
  return true;
}

}  // namespace

int32_t SoftLattice(float v, float step_m) {
  const double steps = std::round(static_cast<double>(v) / static_cast<double>(step_m));
  const double lim = static_cast<double>(kSoftLatticeLimit - 1);
  if (!(steps > -lim)) return static_cast<int32_t>(-(kSoftLatticeLimit - 1));  // NaN too
  if (steps > lim) return static_cast<int32_t>(kSoftLatticeLimit - 1);
  return static_cast<int32_t>(steps);
}

size_t BeginSoftDeltaPayload(uint32_t time_ms, std::span<uint8_t> out) {
  if (out.size() < kSoftDeltaHeaderSize) return 0;
  out[0] = kSoftDeltaFormat;
  StoreU32LE(out.data() + 1, time_ms);
  return kSoftDeltaHeaderSize;
}

size_t EncodeSoftDeltaRecord(const SoftDeltaRecordInput& in, std::span<uint8_t> out,
                             SoftDeltaScratch* scratch, uint32_t* count, uint8_t* mode_out) {
  *count = 0;
  const size_t total = in.q.size() / 3;
  if (in.q.size() % 3 != 0 || in.first >= total || in.max_count == 0 || total > UINT32_MAX) return 0;
  if (out.size() <= kMaxRecordHeader) return 0;
  uint32_t n = static_cast<uint32_t>(std::min<size_t>(in.max_count, total - in.first));
  scratch->coded.resize(out.size());
  for (int attempt = 0; attempt < 24 && n >= 1; ++attempt) {
    Choice c = ChooseMode(in, n, &scratch->residuals);
    const size_t size = in.q.size();
    // Motion contexts (kSoftModeMotion) are decodable but not chosen: on the Bunny poke they
    // cost 1.5 % more than without (the extra contexts adapt more slowly than they gain).
    (void)size;
    const bool motion = (c.mode & kSoftModeMotion) != 0;
    if (!Residuals(in, n, c.mode, c.offset, &scratch->residuals)) return 0;  // keyframes always fit the range
    uint8_t header[kMaxRecordHeader];
    size_t h = 0;
    auto put = [&](uint32_t v) { h += PutVarint32(v, std::span<uint8_t>(header + h, kMaxRecordHeader - h)); };
    put(in.entity_id);
    put(in.version);
    put(in.age_ms);
    put(static_cast<uint32_t>(total));
    put(in.first);
    put(n);
    header[h++] = c.mode;
    const uint8_t predictor = c.mode & 3;
    if (predictor >= kSoftBaseline) put(in.refs.base_distance);
    if (SoftModeUsesBase2(c.mode)) put(in.refs.base2_distance);
    if (c.mode & kSoftModeOffset) {
      for (int32_t o : c.offset) put(ZigZag(o));
    }
    const size_t room = out.size() - h;
    const size_t coded = CodeResiduals(scratch->residuals, in.refs, motion, in.first,
                                       std::span<uint8_t>(scratch->coded.data(), room));
    const size_t length_bytes = coded < 128 ? 1 : coded < 16384 ? 2 : 3;
    if (coded != SIZE_MAX) {
      if (h + length_bytes + coded <= out.size()) {
        put(static_cast<uint32_t>(coded));
        std::memcpy(out.data(), header, h);
        std::memcpy(out.data() + h, scratch->coded.data(), coded);
        *count = n;
        if (mode_out != nullptr) *mode_out = c.mode;
        return h + coded;
      }
    }
    // Too large: shrink in proportion (overflowed: at least halve).
    const double need = coded != SIZE_MAX ? static_cast<double>(h + length_bytes + coded) : 2.0 * static_cast<double>(out.size());
    const uint32_t next = static_cast<uint32_t>(static_cast<double>(n) * static_cast<double>(out.size()) / need * 0.95);
    n = std::min(n - 1, next);
  }
  return 0;
}

Status ParseSoftDeltaRecord(std::span<const uint8_t> payload, uint32_t payload_time_ms,
                            uint32_t max_total, size_t* pos, SoftDeltaRecord* r) {
  const Status malformed = Status::Malformed("malformed soft delta record");
  uint32_t age = 0;
  if (!GetVarint(payload, pos, &r->entity_id) || !GetVarint(payload, pos, &r->version) ||
      !GetVarint(payload, pos, &age) || !GetVarint(payload, pos, &r->total) ||
      !GetVarint(payload, pos, &r->first) || !GetVarint(payload, pos, &r->count)) {
    return malformed;
  }
  r->time_ms = payload_time_ms - age;
  if (r->version == 0 || r->total == 0 || r->total > max_total || r->count == 0 ||
      r->first >= r->total || r->count > r->total - r->first || *pos >= payload.size()) {
    return malformed;
  }
  r->mode = payload[(*pos)++];
  const uint8_t predictor = r->mode & 3;
  if ((r->mode & ~uint8_t{0x1F}) != 0 || predictor > kSoftExtrapolate ||
      (predictor == kSoftKeyframe && (r->mode & kSoftModeMotion) != 0)) {
    return malformed;
  }
  r->base_version = r->base2_version = 0;
  if (predictor >= kSoftBaseline) {
    uint32_t d = 0;
    if (!GetVarint(payload, pos, &d) || d == 0 || d >= r->version) return malformed;
    r->base_version = r->version - d;
  }
  if (SoftModeUsesBase2(r->mode)) {
    uint32_t d = 0;
    if (!GetVarint(payload, pos, &d) || d == 0 || d >= r->base_version) return malformed;
    r->base2_version = r->base_version - d;
  }
  for (int32_t& o : r->offset) o = 0;
  if (r->mode & kSoftModeOffset) {
    for (int32_t& o : r->offset) {
      uint32_t z = 0;
      if (!GetVarint(payload, pos, &z)) return malformed;
      o = UnZigZag(z);
      if (o <= -kSoftLatticeLimit || o >= kSoftLatticeLimit) return malformed;
    }
  }
  uint32_t length = 0;
  if (!GetVarint(payload, pos, &length) || length > payload.size() - *pos) return malformed;
  r->coded = payload.subspan(*pos, length);
  *pos += length;
  return Status::Ok();
}

Status DecodeSoftDeltaResiduals(const SoftDeltaRecord& r, const SoftDeltaRefs& refs,
                                std::span<int32_t> q_out) {
  const Status malformed = Status::Malformed("soft delta residuals out of range");
  const size_t size = size_t{r.total} * 3;
  const uint8_t predictor = r.mode & 3;
  if (q_out.size() != size) return Status::InvalidArgument("output of another size");
  if (predictor >= kSoftBaseline && refs.base.size() != size) return Status::NotFound("baseline missing");
  if (SoftModeUsesBase2(r.mode) && refs.base2.size() != size) return Status::NotFound("second baseline missing");
  if (predictor == kSoftExtrapolate && !ExtrapolationAllowed(refs)) return malformed;
  const bool motion = (r.mode & kSoftModeMotion) != 0;
  RangeDecoder rc(r.coded);
  ResidualModel model;
  int64_t prev_r[3] = {0, 0, 0};
  int64_t prev_e[3] = {0, 0, 0};
  for (uint32_t i = 0; i < r.count; ++i) {
    const size_t p = size_t{r.first} + i;
    bool earlier = false;
    for (int a = 0; a < 3; ++a) {
      const int64_t v = DecodeResidual(rc, model, a, Context(prev_r[a], earlier),
                                       MotionContext(refs, motion, p * 3 + static_cast<size_t>(a)));
      prev_r[a] = v;
      earlier |= v != 0;
      int64_t e = v;
      if (r.mode & kSoftModeDiff) {
        e = v + prev_e[a];
        prev_e[a] = e;
        if (e <= -2 * kResidualLimit || e >= 2 * kResidualLimit) return malformed;
      }
      const size_t k = p * 3 + static_cast<size_t>(a);
      const int64_t q = Predict(predictor, refs, k) + r.offset[a] + e;
      if (q <= -kSoftLatticeLimit || q >= kSoftLatticeLimit) return malformed;
      q_out[k] = static_cast<int32_t>(q);
    }
  }
  return Status::Ok();
}

}  // namespace edgephys
