// codec-sweep: state format 2 (protocol/delta_codec.h) bandwidth vs accuracy, offline.
//
// One DeltaEncoder -> DeltaDecoder stream (one receiver) per configuration, no sockets. At every
// tick (`rate_hz`) the sender samples each object's Motion at the tick's ms timestamp (the
// float truth), asks DeltaEncoder::NeedsUpdate (selective sync: position threshold and
// rotation threshold = threshold * rotation_threshold_deg_per_m; resend_after as the relay
// computes it, 1.25 * rtt + 50 ms with rtt = one tick), and adds the objects that need an
// update, in id order, to payloads of kMaxUnreliablePayload (1179) bytes, starting a new payload
// when one is full. Every payload counts its size plus 21 bytes of connection/chunk headers
// (the 18-byte connection header and the 3-byte unreliable chunk header; UDP/IP not counted).
// Payloads are "sent" with consecutive 16-bit packet sequences, lost with probability `loss`
// (default 0), otherwise decoded at once; the receiver's acknowledgements reach the encoder one
// tick later (OnPacketAcked before the next tick's NeedsUpdate).
//
// Errors, over the measured ticks (after `warmup_s`): for every object at every tick, the state
// the receiver holds (the last decoded one; skipped objects keep theirs) against the float truth
// at that tick's send time -- quantisation error plus what selective sync let drift; and, for
// the records actually decoded, the pure quantisation error (`update_*`).
//
// The sweep varies one dimension at a time around the defaults (1 mm step, 0.1 deg bound,
// 0.5 mm / 0.05 deg thresholds): every step with the default bound and thresholds, every bound
// with the default step and thresholds, every threshold with the default step and bound.
//
// The motion: like relay-compare (loadgen/motion.h, 1.5 m/s, 90 deg/s), except that a fraction
// `slow_fraction` of the objects (default a quarter, spread evenly over the ids) only creeps
// (`slow_motion`, default 5 mm/s and 0.5 deg/s): the creeping objects are the ones whose changes
// can stay under the thresholds. --slow-fraction 0 gives the plain motion.
//
// Cost: objects * rate * (warmup + duration) encodes + decodes per configuration.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "loadgen/motion.h"
#include "protocol/connection.h"
#include "protocol/packet_seal.h"

namespace edgephys::loadgen {

// Bytes counted per packet beyond its state payload, as on the wire: the connection and
// unreliable chunk headers (21) and the seal (24, protocol/packet_seal.h).
inline constexpr size_t kPacketHeaderBytes = kMaxPacketSize - kMaxUnreliablePayload + kSealOverhead;

// The members --json echoes under "options" appear there under their own names.
struct CodecSweepOptions {
  std::vector<double> steps_m = {0.0005, 0.001, 0.002, 0.005};
  std::vector<double> rotation_bounds_deg = {0.05, 0.1, 0.2, 0.5};
  std::vector<double> thresholds_m = {0, 0.0005, 0.001, 0.005};
  double default_position_step_m = 0.001;
  double default_rotation_bound_deg = 0.1;
  double default_threshold_m = 0.0005;
  double rotation_threshold_deg_per_m = 100;  // 0.5 mm -> 0.05 deg (the relay's defaults)
  uint32_t objects = 128;
  double rate_hz = 12;
  double duration_s = 10;  // measured seconds per configuration
  double warmup_s = 1;     // first keyframes; not measured
  double loss = 0;
  MotionParams motion;
  double slow_fraction = 0.25;
  MotionParams slow_motion{0.005, 0.5, 1};  // seed taken from `motion`
};

// Member names are the --json field names of a result.
struct CodecSweepResult {
  std::string dimension;  // "step", "rotation_bound" or "threshold"
  double value = 0;       // the swept parameter's value (m or deg)
  double position_step_m = 0, rotation_bound_deg = 0;
  double position_threshold_m = 0, rotation_threshold_deg = 0;
  double bytes_per_s_per_receiver = 0;  // payloads + 21 bytes per packet
  double payload_bytes_per_s = 0;
  double packets_per_s = 0;
  double updates_per_s = 0;
  double bytes_per_update = 0;  // incl. headers
  double keyframe_frac = 0;     // of the records sent
  double pos_err_max_m = 0, pos_err_p99_m = 0;
  double rot_err_max_deg = 0, rot_err_p99_deg = 0;
  double update_pos_err_max_m = 0, update_rot_err_max_deg = 0;
  uint64_t unresolved_references = 0;
  uint64_t samples = 0;
};

std::vector<CodecSweepResult> RunCodecSweep(const CodecSweepOptions& options);

}  // namespace edgephys::loadgen
