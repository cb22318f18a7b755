#include "protocol/quantize.h"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace edgephys {
namespace {

constexpr uint32_t kMaxLatticeIndex = (1u << 30) - 1;

int BitsFor(uint64_t max_value) {
  int bits = 0;
  while (bits < 64 && (max_value >> bits) != 0) ++bits;
  return bits;
}

}  // namespace

double RotationErrorBoundRad(int32_t rotation_max) {
  const double s = 1.0 / (std::sqrt(2.0) * rotation_max);
  const double d = std::sqrt(3.0) * s / 2.0;
  const double r = std::sqrt(3.0) / 2.0 + d;
  if (r >= 1.0) return std::numbers::pi;
  return 2.0 * d / std::sqrt(1.0 - r * r);
}

Result<QuantizationParams> MakeQuantizationParams(const QuantizationConfig& c) {
  const Status bad = Status::InvalidArgument("bad quantization config");
  QuantizationParams p;
  p.config = c;
  const float mins[3] = {c.bounds_min.x, c.bounds_min.y, c.bounds_min.z};
  const float maxs[3] = {c.bounds_max.x, c.bounds_max.y, c.bounds_max.z};
  if (!std::isfinite(c.position_step_m) || !(c.position_step_m > 0)) return bad;
  p.step = c.position_step_m;
  for (int a = 0; a < 3; ++a) {
    if (!std::isfinite(mins[a]) || !std::isfinite(maxs[a]) || !(maxs[a] > mins[a])) return bad;
    p.origin[a] = mins[a];
    const double levels = std::ceil((static_cast<double>(maxs[a]) - mins[a]) / p.step);
    if (!(levels <= kMaxLatticeIndex)) return bad;
    p.max_index[a] = static_cast<uint32_t>(levels);
    p.position_bits[a] = BitsFor(p.max_index[a]);
  }
  const double bound_deg = c.rotation_error_deg;
  if (!std::isfinite(bound_deg) || bound_deg < 1e-4 || bound_deg > 10.0) return bad;
  const double bound = bound_deg * std::numbers::pi / 180.0 * (1.0 - 1e-4);
  int32_t m = std::max<int32_t>(1, static_cast<int32_t>(std::ceil(std::sqrt(6.0) / bound)));
  while (RotationErrorBoundRad(m) > bound) ++m;
  p.rotation_max = m;
  p.rotation_bits = BitsFor(2 * static_cast<uint64_t>(m));
  return p;
}

bool QuantizePosition(const QuantizationParams& p, const Vec3f& position,
                      std::array<uint32_t, 3>* out) {
  const float v[3] = {position.x, position.y, position.z};
  bool exact = true;
  for (int a = 0; a < 3; ++a) {
    double i = std::nearbyint((static_cast<double>(v[a]) - p.origin[a]) / p.step);
    if (!std::isfinite(i)) {
      i = 0;
      exact = false;
    } else if (i < 0) {
      i = 0;
      exact = false;
    } else if (i > p.max_index[a]) {
      // Within half a step above the last lattice point still rounds to it exactly.
      i = p.max_index[a];
      exact = false;
    }
    (*out)[a] = static_cast<uint32_t>(i);
  }
  return exact;
}

bool QuantizeRotation(const QuantizationParams& p, const Quatf& rotation, QuantizedRotation* out) {
  double q[4] = {rotation.x, rotation.y, rotation.z, rotation.w};
  const double n2 = q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3];
  bool ok = std::isfinite(n2) && n2 > 1e-12;
  if (!ok) {
    q[0] = q[1] = q[2] = 0;
    q[3] = 1;
  } else {
    const double inv = 1.0 / std::sqrt(n2);
    for (double& c : q) c *= inv;
  }
  int largest = 0;
  for (int i = 1; i < 4; ++i) {
    if (std::fabs(q[i]) > std::fabs(q[largest])) largest = i;
  }
  const double sign = q[largest] < 0 ? -1.0 : 1.0;
  const double scale = std::sqrt(2.0) * p.rotation_max;
  out->largest = static_cast<uint8_t>(largest);
  int k = 0;
  for (int i = 0; i < 4; ++i) {
    if (i == largest) continue;
    double c = std::nearbyint(sign * q[i] * scale);
    c = std::clamp(c, -static_cast<double>(p.rotation_max), static_cast<double>(p.rotation_max));
    out->c[k++] = static_cast<int32_t>(c);
  }
  return ok;
}

bool QuantizeState(const QuantizationParams& p, const EntityState& state, QuantizedState* out) {
  const bool a = QuantizePosition(p, state.position, &out->position);
  const bool b = QuantizeRotation(p, state.rotation, &out->rotation);
  return a && b;
}

Vec3f DequantizePosition(const QuantizationParams& p, const std::array<uint32_t, 3>& position) {
  return {static_cast<float>(p.origin[0] + position[0] * p.step),
          static_cast<float>(p.origin[1] + position[1] * p.step),
          static_cast<float>(p.origin[2] + position[2] * p.step)};
}

Quatf DequantizeRotation(const QuantizationParams& p, const QuantizedRotation& r) {
  const double s = 1.0 / (std::sqrt(2.0) * p.rotation_max);
  double q[4];
  double sum = 0;
  int k = 0;
  for (int i = 0; i < 4; ++i) {
    if (i == r.largest) continue;
    q[i] = r.c[k++] * s;
    sum += q[i] * q[i];
  }
  q[r.largest & 3] = std::sqrt(std::max(0.0, 1.0 - sum));
  const double inv = 1.0 / std::sqrt(std::max(sum, 1.0));  // only shrinks invalid (|v|>1) input
  return {static_cast<float>(q[0] * inv), static_cast<float>(q[1] * inv),
          static_cast<float>(q[2] * inv), static_cast<float>(q[3] * inv)};
}

int64_t IntegerSqrt(int64_t v) {
  if (v <= 0) return 0;
  int64_t r = static_cast<int64_t>(std::sqrt(static_cast<double>(v)));
  while (r > 0 && r * r > v) --r;
  while ((r + 1) * (r + 1) <= v) ++r;
  return r;
}

std::array<int32_t, 4> RotationToInt4(const QuantizationParams& p, const QuantizedRotation& r) {
  std::array<int32_t, 4> out{};
  const int64_t m = p.rotation_max;
  int64_t rest = 2 * m * m;
  int k = 0;
  for (int i = 0; i < 4; ++i) {
    if (i == (r.largest & 3)) continue;
    out[i] = r.c[k];
    rest -= static_cast<int64_t>(r.c[k]) * r.c[k];
    ++k;
  }
  out[r.largest & 3] = static_cast<int32_t>(IntegerSqrt(rest));
  return out;
}

}  // namespace edgephys
