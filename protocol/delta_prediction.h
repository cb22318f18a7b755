// Prediction and parameter packing shared by state format 2 (protocol/delta_codec.h) and
// format 9 (protocol/shared_delta_codec.h): both ends of both formats run exactly this integer
// arithmetic (docs/protocol.md §5b "Prediction"). Internal to the codecs; not a public API.
//
// Thread-safety: pure functions over values. Cost O(1), no allocation.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>

#include "protocol/bit_stream.h"
#include "protocol/delta_codec.h"
#include "protocol/quantize.h"

namespace edgephys::delta_internal {

using Sample = DeltaEncoder::Sample;
using History = DeltaEncoder::History;

struct Timing {
  int order = 0;  // effective order after the availability / gap checks
  int64_t h = 0, h2 = 0, h1 = 0;
};
// The effective prediction order and time steps for predicting `hist` to `time_ms`.
Timing MakeTiming(const History& hist, int order, uint32_t time_ms);

struct Prediction {
  std::array<uint32_t, 3> pos{};
  std::array<int64_t, 4> rot{};
  int largest = 3;  // index of the largest |rot| component (lowest on ties)
};
void PredictPosition(const QuantizationParams& p, const History& hist, const Timing& t,
                     Prediction* out);
void PredictRotation(const QuantizationParams& p, const History& hist, const Timing& t,
                     Prediction* out);
// The predicted smallest-three components for dropped index `largest`.
std::array<int32_t, 3> PredictedComponents(const QuantizationParams& p, const Prediction& pr,
                                           int largest);

Sample MakeSample(const QuantizedState& q, const std::array<int32_t, 4>& rot4, uint32_t time_ms);
Sample MakeSample(const QuantizationParams& p, const QuantizedState& q, uint32_t time_ms);
bool SameLattice(const PreparedState& s, const QuantizationParams& p);
// (s, base.s0, base.s1), depth base.depth + 1 (max 3); a keyframe's (s, s, s), depth 1.
History ExtendHistory(const History* base, const Sample& s);

// The 16-bit params field of formats 2 and 9.
uint16_t PackParams(const int k[2], const bool mask[2], const int order[2]);
bool UnpackParams(uint16_t v, int k[2], bool mask[2], int order[2]);

// One entity record of formats 2 and 9 as it stands in the bit stream (the reference not yet
// resolved): a keyframe's quantised state, or a delta's reference distance and residuals.
struct RecordFields {
  uint32_t id = 0;
  bool keyframe = false;
  QuantizedState q;            // keyframe only
  int64_t distance = 0;        // delta only: payload counters (format 2) or ticks (format 9)
  bool same_index = true;      // delta: the rotation's largest component is the predicted one
  uint64_t index = 0;          // delta: otherwise, this one
  int32_t pos_res[3] = {0, 0, 0};
  int32_t rot_res[3] = {0, 0, 0};
};
// Reads record `i` of a payload with coding parameters k/mask (untrusted input): false when
// malformed (truncated, ids not increasing, values out of range, distance outside
// 1..kMaxReferenceDistance). `prev_id` and `prev_distance` carry the record-to-record context
// (start at 0 and 1).
bool ReadRecord(BitReader& r, const QuantizationParams& p, const int k[2], const bool mask[2],
                uint32_t i, uint32_t* prev_id, uint32_t* prev_distance, RecordFields* f);
// A delta record's state from its reference's history, predicted at `time_ms` with the given
// orders; false when the result falls outside the lattice (malformed input).
bool ReconstructDelta(const QuantizationParams& p, const History& h, const int order[2],
                      uint32_t time_ms, const RecordFields& f, QuantizedState* q);

// Encoder side, both formats: a delta record's residuals against its reference's history
// predicted at `time_ms`, for the orders in use (`order`: position, rotation) or, with
// `all_orders`, for each of the three (the adaptive parameters' statistics).
struct Residuals {
  std::array<int32_t, 3> pos[3]{};
  std::array<int32_t, 3> rot[3]{};
  bool pos_zero[3] = {}, rot_zero[3] = {}, rot_same[3] = {};
};
void ComputeResiduals(const QuantizationParams& p, const History& h, const QuantizedState& q,
                      uint32_t time_ms, const int order[2], bool all_orders, Residuals* out);
// Writes a keyframe record's state (every field at full precision, after its reference symbol).
bool WriteKeyframeState(BitWriter& w, const QuantizationParams& p, const QuantizedState& q);
// Writes a delta record's body after its reference symbol: the mask bits, then the position
// and rotation residuals of orders `order` (a field whose residuals are all zero is skipped
// where `mask` allows). `*pos_coded`, `*rot_coded`: which were written; `*at_mask`: the bit
// position after the mask bits, `*at_pos` after the position (record statistics). False: out
// of room (the writer is then to be rewound by the caller).
struct DeltaBodyMarks {
  bool pos_coded = false, rot_coded = false;
  size_t at_mask = 0, at_pos = 0;
};
bool WriteDeltaBody(BitWriter& w, const Residuals& r, const QuantizedState& q, const int k[2],
                    const bool mask[2], const int order[2], DeltaBodyMarks* marks);

// Completes a payload of either format whose header (`header_size` bytes) is written and whose
// record stream (`body` bytes) was written at `stream_start`: puts the record count's varint
// after the header and moves the stream behind it. Returns the payload's size.
size_t PlaceRecordStream(uint8_t* payload, size_t header_size, size_t count, size_t stream_start,
                         size_t body);

// Decoder side, both formats: keeps the ring's highest versions. Stores (`version`, `hist`) in
// a free entry or over the lowest version held, unless that version is already held or every
// held one is newer. `field` names the entry's version member.
template <typename Entry, size_t N>
void StoreVersion(std::array<Entry, N>& ring, int64_t Entry::*field, int64_t version,
                  const History& hist) {
  Entry* slot = nullptr;
  for (Entry& e : ring) {
    if (e.valid && e.*field == version) return;  // a duplicate payload
    if (!e.valid) {
      if (slot == nullptr || slot->valid) slot = &e;
    } else if (slot == nullptr || (slot->valid && e.*field < slot->*field)) {
      slot = &e;
    }
  }
  if (!slot->valid || slot->*field < version) {
    slot->valid = true;
    slot->*field = version;
    slot->hist = hist;
  }
}

// Appends entity `id`'s state `q` to `out` if `version` is newer than the newest output for it
// (`*newest_output`, updated); false when it is not (a stale record).
inline bool OutputIfNewer(const QuantizationParams& p, uint32_t id, const QuantizedState& q,
                          int64_t version, int64_t* newest_output, StateBatch* out) {
  if (version <= *newest_output) return false;
  *newest_output = version;
  EntityState st;
  st.entity_id = id;
  st.position = DequantizePosition(p, q.position);
  st.rotation = DequantizeRotation(p, q.rotation);
  out->states.push_back(st);
  return true;
}

// Selective sync, both formats: whether a state the client holds (an encoder entry with a
// lazily dequantised copy: members q, has_float, position, rotation, the last three mutable)
// is within the thresholds of `truth`. A field whose quantised truth equals the held state's
// counts as within (thresholds finer than the lattice would otherwise resend a resting entity
// forever); the truth is quantised only when a threshold test fails, once per test object.
class WithinThresholds {
 public:
  // `pos2`: squared position threshold (m^2); `min_dot`: cos(rotation threshold / 2);
  // `lattice_reach2`, `lattice_min_dot`: beyond these a truth cannot quantise to the held state.
  WithinThresholds(const QuantizationParams& p, const EntityState& truth, double pos2,
                   double min_dot, double lattice_reach2, double lattice_min_dot)
      : p_(p), truth_(truth), pos2_(pos2), min_dot_(min_dot), reach2_(lattice_reach2),
        lattice_min_dot_(lattice_min_dot) {}

  template <typename Held>
  bool operator()(const Held& e) {
    if (!e.has_float) {
      e.position = DequantizePosition(p_, e.q.position);
      e.rotation = DequantizeRotation(p_, e.q.rotation);
      e.has_float = true;
    }
    const double dx = static_cast<double>(e.position.x) - truth_.position.x;
    const double dy = static_cast<double>(e.position.y) - truth_.position.y;
    const double dz = static_cast<double>(e.position.z) - truth_.position.z;
    const double d2 = dx * dx + dy * dy + dz * dz;
    if (d2 > pos2_) {
      if (d2 > reach2_) return false;
      if (!have_pos_) {
        (void)QuantizePosition(p_, truth_.position, &truth_pos_);
        have_pos_ = true;
      }
      if (truth_pos_ != e.q.position) return false;
    }
    const Quatf& a = e.rotation;
    const Quatf& b = truth_.rotation;
    const double dot = static_cast<double>(a.x) * b.x + static_cast<double>(a.y) * b.y +
                       static_cast<double>(a.z) * b.z + static_cast<double>(a.w) * b.w;
    if (std::fabs(dot) < min_dot_) {
      if (std::fabs(dot) < lattice_min_dot_) return false;
      if (!have_rot_) {
        (void)QuantizeRotation(p_, truth_.rotation, &truth_rot_);
        have_rot_ = true;
      }
      if (!(truth_rot_ == e.q.rotation)) return false;
    }
    return true;
  }

 private:
  const QuantizationParams& p_;
  const EntityState& truth_;
  double pos2_, min_dot_, reach2_, lattice_min_dot_;
  std::array<uint32_t, 3> truth_pos_{};
  QuantizedRotation truth_rot_;
  bool have_pos_ = false, have_rot_ = false;
};

}  // namespace edgephys::delta_internal
