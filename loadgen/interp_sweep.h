// interp-sweep: client-side smoothing accuracy vs send rate (offline, deterministic, seeded).
//
// For every network condition and send rate, each object's sender samples its Motion
// (loadgen/motion.h) at the send rate (the sample instant is the ms timestamp the protocol
// carries, so the timestamp is exact), optionally quantises the pose like state format 2
// (protocol/quantize.h: --position-step / --rotation-bound, default 1 mm / 0.1 deg), and
// "sends" it. Each object has its own independent stream (equivalent to one packet per object,
// or independent receivers): every snapshot is lost with probability `loss` and otherwise
// arrives after `latency_s + U(-jitter_s, +jitter_s)` (clamped at 0), so with jitter larger than
// half the send interval arrivals are reordered. The receiver inserts arrivals into a
// SnapshotBuffer (client/snapshot_buffer.h, default config) and renders at `render_hz`: once
// per frame RenderTime(now), then Sample() with every interpolator on the same buffer (so all
// interpolators see exactly the same arrivals and playout clock). The error of a frame is
// Compare(rendered pose, Motion::At(render time)) -- the render time is in the sender's clock,
// which is the truth's clock. Frames in the first `warmup_s` are not measured.
//
// Results per (network, rate, interpolator): position error max / p99 / mean (m), rotation
// error max / p99 / mean (deg), mean display delay (local now - render time: everything from
// the sender's sample to the screen, base latency included) and mean buffer delay (the
// SnapshotBuffer's current_delay_s: behind the estimated sender now, base latency excluded),
// and the fraction of frames rendered past the newest snapshot (extrapolated or held).
//
// Cost: objects * (warmup + duration) * render_hz frames per (network, rate), each with one
// Sample() per interpolator.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "client/interpolation.h"
#include "loadgen/motion.h"

namespace edgephys::loadgen {

struct NetworkCondition {
  std::string name;         // "clean", "loss5_jitter20"
  double latency_s = 0.030; // base one-way latency
  double jitter_s = 0;      // uniform +-jitter_s on top of the latency
  double loss = 0;          // independent loss probability per snapshot
};

struct InterpSweepOptions {
  std::vector<double> rates_hz = {6, 12, 24, 30, 48, 60};
  std::vector<Interpolator> interpolators = {Interpolator::kLerpSlerp, Interpolator::kDualQuatDlb,
                                             Interpolator::kDualQuatSclerp,
                                             Interpolator::kHermite, Interpolator::kNone};
  std::vector<NetworkCondition> networks = {{"clean", 0.030, 0, 0},
                                            {"loss5_jitter20", 0.030, 0.020, 0.05}};
  double duration_s = 20;  // measured seconds per (network, rate)
  double warmup_s = 1.0;   // rendered but not measured
  double render_hz = 90;
  uint32_t objects = 16;
  MotionParams motion;     // motion.seed also seeds the network simulation
  bool quantize = true;
  float position_step_m = 0.001f;
  float rotation_bound_deg = 0.1f;
};

// Member names are the --json field names of a result.
struct InterpSweepResult {
  std::string network;
  double rate_hz = 0;
  Interpolator interpolator = Interpolator::kLerpSlerp;
  double pos_err_max_m = 0, pos_err_p99_m = 0, pos_err_mean_m = 0;
  double rot_err_max_deg = 0, rot_err_p99_deg = 0, rot_err_mean_deg = 0;
  double display_delay_ms = 0;  // mean (local now - render time)
  double buffer_delay_ms = 0;   // mean SnapshotBuffer::current_delay_s
  double extrapolated_frac = 0; // frames with render time past the newest snapshot
  double snapshots_lost_frac = 0;
  uint64_t frames = 0;          // measured frames (all objects)
};

// "lerp-slerp", "dq-dlb", "dq-sclerp", "hermite", "none" (underscores accepted too).
bool ParseInterpolator(const std::string& name, Interpolator* out);

// One result per (network, rate, interpolator), in that nesting order.
std::vector<InterpSweepResult> RunInterpSweep(const InterpSweepOptions& options);

}  // namespace edgephys::loadgen
