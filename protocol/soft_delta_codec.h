// Soft-body state format 11, "soft delta" (docs/protocol.md §5f): a soft body's particles as
// quantised residuals against a prediction from versions the receiver acknowledged, range-coded
// (protocol/range_coder.h). Relay -> clients on the unreliable channel. Format 5
// (protocol/soft_body_codec.h) stays decodable.
//
// Lattice: a particle p is sent as integer lattice coordinates q = round(p / step) per axis
// (step = the room's position step, default 1 mm; |q| < kSoftLatticeLimit), decoded as q x step:
// the error against what was sent is <= step / 2 per axis (0.87 mm at 1 mm).
//
// Payload: u8 format (11) | u32 time (ms) | records back to back, each covering particles
// [first, first + count) of one version of one body. A record's prediction of particle i:
//   predictor 0 (keyframe)       0
//   predictor 1 (baseline)       b_i, the baseline version's lattice coordinates
//   predictor 2 (extrapolation)  b_i + round((b_i - b2_i) x (t_v - t_b) / (t_b - t_b2)), two
//                                baselines and the versions' times (ms), clamped to the lattice
// e_i = q_i - prediction - offset (offset: the record's mean motion, optional); the coded
// residual is e_i, or with neighbour differencing e_i - e_(i-1) (e_(first-1) = 0): neighbouring
// particles move together. Residuals are coded per particle x, y, z with adaptive binary models
// (zero flag, sign, Elias-gamma length, first mantissa bit) whose context is the size of the
// previous particle's residual on that axis and whether an earlier axis of this particle was
// non-zero, and (mode bit 4) how far the coordinate moved between the two baselines; a body at
// rest codes ~0.01 bit per axis.
//
// The encoder estimates the cost of every predictor it has references for, with and without
// differencing and offset, and codes the cheapest; it shrinks `count` until the record fits.
//
// Thread-safety: pure functions. Cost: O(count) (the estimate visits each particle ~6 times);
// no allocation except growing the caller's scratch.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "protocol/status.h"

namespace edgephys {

inline constexpr uint8_t kSoftDeltaFormat = 11;
inline constexpr size_t kSoftDeltaHeaderSize = 1 + 4;
// Lattice coordinates are within (-limit, limit): 2^30 steps (1,073 km at 1 mm).
inline constexpr int64_t kSoftLatticeLimit = int64_t{1} << 30;
// Extrapolation needs 1 <= t_b - t_b2 <= this and 0 <= t_v - t_b <= this (ms).
inline constexpr uint32_t kSoftMaxExtrapolationMs = 60000;

enum SoftPredictor : uint8_t { kSoftKeyframe = 0, kSoftBaseline = 1, kSoftExtrapolate = 2 };
inline constexpr uint8_t kSoftModeDiff = 1u << 2;    // neighbour differencing
inline constexpr uint8_t kSoftModeOffset = 1u << 3;  // a mean-motion offset follows
// Residual contexts also use each coordinate's motion between the two baselines (a second
// baseline distance follows; predictor 1 or 2 only).
inline constexpr uint8_t kSoftModeMotion = 1u << 4;
// Whether a record of `mode` references a second baseline.
inline bool SoftModeUsesBase2(uint8_t mode) {
  return (mode & 3) == 2 || ((mode & kSoftModeMotion) != 0 && (mode & 3) != 0);
}

// Lattice coordinates of a position (clamped into the lattice limit).
int32_t SoftLattice(float v, float step_m);

// A record's prediction inputs: the baselines' lattice coordinates (3 x total each, x y z per
// particle) and the versions' times. `base` empty: keyframe only; `base2` empty: no
// extrapolation.
struct SoftDeltaRefs {
  std::span<const int32_t> base;
  uint32_t base_distance = 0;   // version - baseline version (>= 1)
  std::span<const int32_t> base2;
  uint32_t base2_distance = 0;  // baseline version - second baseline version (>= 1)
  uint32_t dt_ms = 0;           // t_v - t_b
  uint32_t base_dt_ms = 0;      // t_b - t_b2
};

struct SoftDeltaRecordInput {
  uint32_t entity_id = 0;
  uint32_t version = 0;
  uint32_t age_ms = 0;  // payload time - the version's time
  std::span<const int32_t> q;  // the version: 3 x total lattice coordinates
  uint32_t first = 0;
  uint32_t max_count = 0;  // encode at most this many particles from `first`
  SoftDeltaRefs refs;
};

struct SoftDeltaScratch {
  std::vector<int64_t> residuals;
  std::vector<uint8_t> coded;
};

// Appends one record for particles [first, first + n) of `in` to `out` and returns its size
// (0 if not even one particle fits); `*count` is set to n (>= 1 on success). `*mode` (may be
// null) receives the mode byte used.
size_t EncodeSoftDeltaRecord(const SoftDeltaRecordInput& in, std::span<uint8_t> out,
                             SoftDeltaScratch* scratch, uint32_t* count, uint8_t* mode);

// Writes the payload header (format, time); returns kSoftDeltaHeaderSize (0 if `out` is too
// small).
size_t BeginSoftDeltaPayload(uint32_t time_ms, std::span<uint8_t> out);

// One parsed record (its residual stream is decoded against the references separately).
struct SoftDeltaRecord {
  uint32_t entity_id = 0;
  uint32_t version = 0;
  uint32_t time_ms = 0;  // the version's time: payload time - age
  uint32_t total = 0;
  uint32_t first = 0;
  uint32_t count = 0;
  uint8_t mode = 0;
  uint32_t base_version = 0;   // predictor >= 1
  uint32_t base2_version = 0;  // predictor 2, or motion contexts
  int32_t offset[3] = {0, 0, 0};
  std::span<const uint8_t> coded;
};

// Parses the record starting at `*pos` of `payload` (after the header) and advances `*pos`.
// Untrusted input: kMalformed on truncation, a count of 0, first + count > total, total above
// `max_total`, an unknown mode, baseline distances of 0 or reaching below version 1, offsets
// outside the lattice, or a coded length past the end.
Status ParseSoftDeltaRecord(std::span<const uint8_t> payload, uint32_t payload_time_ms,
                            uint32_t max_total, size_t* pos, SoftDeltaRecord* record);

// Decodes `record`'s residuals against `refs` (base / base2 as for the encoder, with
// base_dt_ms / dt_ms the versions' time differences) into `q_out` (3 x record.total; only the
// record's particles are written). kMalformed if a decoded coordinate leaves the lattice, the
// times do not allow the extrapolation, or a reference is missing or of another size.
Status DecodeSoftDeltaResiduals(const SoftDeltaRecord& record, const SoftDeltaRefs& refs,
                                std::span<int32_t> q_out);

}  // namespace edgephys
