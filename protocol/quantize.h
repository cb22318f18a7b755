// Quantisation of entity transforms for state format 2 (docs/protocol.md §5b).
//
// Position: each axis is mapped to an integer lattice index
//   i = round((x - bounds_min) / step),  clamped to [0, max_index],
//   max_index = ceil((bounds_max - bounds_min) / step).
// Rounding to the nearest lattice point bounds the per-axis error by step/2, hence the
// Euclidean error by step * sqrt(3) / 2 (plus float32 rounding of the dequantised value, which
// is below 1e-7 relative). Coordinates outside the bounds (or non-finite) are clamped and
// reported by the return value.
//
// Rotation ("smallest three"): the unit quaternion is normalised, its largest-magnitude
// component (index 0..3 for x, y, z, w; lowest index on ties) is made positive (q and -q are
// the same rotation: sign canonicalisation), and the other three components, which then lie in
// [-1/sqrt(2), 1/sqrt(2)], are stored as integers c = round(v * sqrt(2) * M) in [-M, M], i.e.
// with a step s = 1 / (sqrt(2) * M). The dropped component is recomputed as
// sqrt(1 - |v|^2) (it is >= 1/2).
//
// Error bound maths. Each stored component errs by at most s/2, so the 3-vector v errs by at
// most d = sqrt(3) * s / 2. The map from v to the point (v, sqrt(1 - |v|^2)) of the unit
// 3-sphere stretches lengths by at most 1 / w, w being the recomputed component along the
// segment between true and stored v; w >= sqrt(1 - (sqrt(3)/2 + d)^2) because |v| <= sqrt(3)/2
// for the true quaternion. So the great-circle angle between the true and the decoded
// quaternion is <= d / w_min, and the rotation angle (twice the quaternion angle) is
//   theta <= 2 * d / sqrt(1 - (sqrt(3)/2 + d)^2)            (~ sqrt(6) / M for large M).
// MakeQuantizationParams picks the smallest M for which this is <= the configured bound
// (times 1 - 1e-4 for float rounding). Default 0.1 degree: M = 1406, 12 bits per component in
// a keyframe (2M + 1 = 2813 values).
//
// Thread-safety: pure functions over values. Cost: O(1), no allocation.
#pragma once

#include <array>
#include <cstdint>

#include "protocol/state_codec.h"
#include "protocol/status.h"

namespace edgephys {

// Per-room quantisation settings. Both ends of a format-2 stream must use the same values
// (the relay tells clients in the room description).
struct QuantizationConfig {
  Vec3f bounds_min{-1000.f, -1000.f, -1000.f};  // metres, room frame
  Vec3f bounds_max{1000.f, 1000.f, 1000.f};     // metres, > bounds_min on every axis
  float position_step_m = 0.001f;               // lattice step (metres), > 0
  float rotation_error_deg = 0.1f;              // max rotation angle error, in (0, 10]
};

// Derived constants; build with MakeQuantizationParams (validates the config).
struct QuantizationParams {
  QuantizationConfig config;
  double origin[3] = {0, 0, 0};  // bounds_min, as double
  double step = 0.001;           // metres
  uint32_t max_index[3] = {0, 0, 0};
  int position_bits[3] = {0, 0, 0};  // bits of a raw lattice index (keyframes)
  int32_t rotation_max = 0;          // M: components are integers in [-M, M]
  int rotation_bits = 0;             // bits of a raw component (keyframes): ceil(log2(2M+1))
};

// kInvalidArgument if a bound is not finite, bounds are empty, the step is not positive, an
// axis needs more than 2^30 lattice points, or the rotation bound is outside (0, 10] degrees
// (or below 1e-4 degree).
Result<QuantizationParams> MakeQuantizationParams(const QuantizationConfig& config);

struct QuantizedRotation {
  uint8_t largest = 3;                // index of the dropped component (0=x .. 3=w)
  std::array<int32_t, 3> c{0, 0, 0};  // the other components in ascending index order
  bool operator==(const QuantizedRotation&) const = default;
};

struct QuantizedState {
  std::array<uint32_t, 3> position{0, 0, 0};  // lattice indices, <= max_index
  QuantizedRotation rotation;
  bool operator==(const QuantizedState&) const = default;
};

// Returns false if the position was clamped (outside the bounds or not finite: NaN maps to 0).
bool QuantizePosition(const QuantizationParams& p, const Vec3f& position,
                      std::array<uint32_t, 3>* out);
// Returns false if the quaternion was not usable (not finite or |q| < 1e-6): identity is used.
// Any non-zero quaternion is normalised first.
bool QuantizeRotation(const QuantizationParams& p, const Quatf& rotation, QuantizedRotation* out);
// Both of the above; false if either reported.
bool QuantizeState(const QuantizationParams& p, const EntityState& state, QuantizedState* out);

// Precondition: indices within max_index / components within [-M, M] (the decoder checks).
Vec3f DequantizePosition(const QuantizationParams& p, const std::array<uint32_t, 3>& position);
Quatf DequantizeRotation(const QuantizationParams& p, const QuantizedRotation& rotation);

// The rotation as four integers on the same scale (unit length = sqrt(2) * M), the dropped
// component recomputed with an exact integer square root. Deterministic on every platform:
// delta prediction runs on these values at both ends.
std::array<int32_t, 4> RotationToInt4(const QuantizationParams& p, const QuantizedRotation& r);

// floor(sqrt(v)) for v >= 0, exact.
int64_t IntegerSqrt(int64_t v);

// Worst-case rotation angle error (radians) of the smallest-three code with limit M, from the
// bound above. Exposed for tests and documentation.
double RotationErrorBoundRad(int32_t rotation_max);

}  // namespace edgephys
