#include "loadgen/codec_sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "client/interpolation.h"
#include "loadgen/stats.h"
#include "protocol/delta_codec.h"
#include "protocol/quantize.h"

namespace edgephys::loadgen {
namespace {


struct Config {
  std::string dimension;
  double value;
  double step_m, bound_deg, threshold_m;
};

PoseError StateError(const EntityState& a, const EntityState& b) {
  return Compare(Pose{a.position, a.rotation}, Pose{b.position, b.rotation});
}

CodecSweepResult RunOne(const CodecSweepOptions& o, const Config& c) {
  CodecSweepResult r;
  r.dimension = c.dimension;
  r.value = c.value;
  r.position_step_m = c.step_m;
  r.rotation_bound_deg = c.bound_deg;
  r.position_threshold_m = c.threshold_m;
  r.rotation_threshold_deg = c.threshold_m * o.rotation_threshold_deg_per_m;

  QuantizationConfig qc;
  qc.position_step_m = static_cast<float>(c.step_m);
  qc.rotation_error_deg = static_cast<float>(c.bound_deg);
  auto params = MakeQuantizationParams(qc);
  if (!params.ok()) {
    std::fprintf(stderr, "codec-sweep: invalid quantisation step %g m / bound %g deg\n", c.step_m,
                 c.bound_deg);
    return r;
  }
  DeltaEncoder encoder(*params);
  DeltaDecoder decoder(*params);

  // Objects: ids 1..n; a `slow_fraction` of them, spread evenly, creep.
  std::vector<Motion> motions;
  MotionParams slow = o.slow_motion;
  slow.seed = o.motion.seed;
  for (uint32_t i = 0; i < o.objects; ++i) {
    const bool is_slow = std::floor((i + 1) * o.slow_fraction) > std::floor(i * o.slow_fraction);
    motions.emplace_back(is_slow ? slow : o.motion, i);
  }
  const uint32_t n = o.objects;
  std::vector<EntityState> held(n);
  std::vector<bool> have(n, false);
  std::vector<EntityState> truth(n);
  std::vector<uint32_t> to_send;
  std::vector<uint16_t> acks_next_tick, acks_now;
  std::vector<uint8_t> buffer(kMaxUnreliablePayload);
  StateBatch batch;
  SplitMix64 rng(o.motion.seed * 0x9E3779B97F4A7C15ull + 17);

  const float pos_thr = static_cast<float>(r.position_threshold_m);
  const float rot_thr = static_cast<float>(r.rotation_threshold_deg);
  const double resend_after = 1.25 / o.rate_hz + 0.05;
  uint16_t sequence = 0;
  bool measuring = false;
  uint64_t bytes = 0, payload_bytes = 0, packets = 0, updates = 0, keyframes0 = 0;
  std::vector<double> pos, rot;
  double update_pos_max = 0, update_rot_max = 0;

  const uint64_t ticks = static_cast<uint64_t>(std::llround((o.warmup_s + o.duration_s) * o.rate_hz));
  const uint64_t warmup_ticks = static_cast<uint64_t>(std::llround(o.warmup_s * o.rate_hz));
  for (uint64_t k = 0; k < ticks; ++k) {
    const double now = static_cast<double>(k) / o.rate_hz;
    const uint32_t time_ms = static_cast<uint32_t>(std::floor(now * 1000.0 + 1e-9));
    const double t = time_ms / 1000.0;
    if (k == warmup_ticks) {
      measuring = true;
      keyframes0 = encoder.stats().keyframes;
    }
    // Acknowledgements of last tick's packets arrive now.
    acks_now.swap(acks_next_tick);
    acks_next_tick.clear();
    for (uint16_t s : acks_now) encoder.OnPacketAcked(s);

    to_send.clear();
    for (uint32_t i = 0; i < n; ++i) {
      truth[i] = motions[i].At(t);
      truth[i].entity_id = i + 1;
      if (encoder.NeedsUpdate(i + 1, truth[i], pos_thr, rot_thr, now, resend_after)) {
        to_send.push_back(i);
      }
    }
    auto flush = [&] {
      const size_t size = encoder.Finish();
      if (size == 0) return;
      const uint16_t seq = sequence++;
      encoder.OnSent(seq, now);
      if (measuring) {
        bytes += size + kPacketHeaderBytes;
        payload_bytes += size;
        ++packets;
      }
      if (rng.Uniform() < o.loss) return;  // lost: neither decoded nor acknowledged
      batch.states.clear();
      if (!decoder.Decode({buffer.data(), size}, &batch).ok()) {
        std::fprintf(stderr, "codec-sweep: decoder rejected a payload\n");
        return;
      }
      for (const EntityState& s : batch.states) {
        if (s.entity_id == 0 || s.entity_id > n) continue;
        const uint32_t i = s.entity_id - 1;
        held[i] = s;
        have[i] = true;
        if (measuring) {
          const PoseError e = StateError(s, truth[i]);
          update_pos_max = std::max(update_pos_max, e.pos_m);
          update_rot_max = std::max(update_rot_max, e.rot_deg);
        }
      }
      acks_next_tick.push_back(seq);
    };
    if (!to_send.empty()) {
      encoder.Begin(buffer, time_ms);
      for (uint32_t i : to_send) {
        if (!encoder.Add(truth[i])) {
          flush();
          encoder.Begin(buffer, time_ms);
          if (!encoder.Add(truth[i])) {
            std::fprintf(stderr, "codec-sweep: one state does not fit a payload\n");
            continue;
          }
        }
        if (measuring) ++updates;
      }
      flush();
    }
    if (!measuring) continue;
    for (uint32_t i = 0; i < n; ++i) {
      if (!have[i]) continue;
      const PoseError e = StateError(held[i], truth[i]);
      pos.push_back(e.pos_m);
      rot.push_back(e.rot_deg);
    }
  }

  const double seconds = static_cast<double>(ticks - warmup_ticks) / o.rate_hz;
  r.bytes_per_s_per_receiver = static_cast<double>(bytes) / seconds;
  r.payload_bytes_per_s = static_cast<double>(payload_bytes) / seconds;
  r.packets_per_s = static_cast<double>(packets) / seconds;
  r.updates_per_s = static_cast<double>(updates) / seconds;
  r.bytes_per_update = updates > 0 ? static_cast<double>(bytes) / static_cast<double>(updates) : 0;
  r.keyframe_frac = updates > 0 ? static_cast<double>(encoder.stats().keyframes - keyframes0) /
                                      static_cast<double>(updates)
                                : 0;
  r.pos_err_max_m = Max(pos);
  r.pos_err_p99_m = Percentile(pos, 99);
  r.rot_err_max_deg = Max(rot);
  r.rot_err_p99_deg = Percentile(rot, 99);
  r.update_pos_err_max_m = update_pos_max;
  r.update_rot_err_max_deg = update_rot_max;
  r.unresolved_references = decoder.stats().unresolved_references;
  r.samples = pos.size();
  return r;
}

}  // namespace

std::vector<CodecSweepResult> RunCodecSweep(const CodecSweepOptions& o) {
  std::vector<Config> configs;
  const double step = o.default_position_step_m, bound = o.default_rotation_bound_deg,
               thr = o.default_threshold_m;
  for (double v : o.steps_m) configs.push_back({"step", v, v, bound, thr});
  for (double v : o.rotation_bounds_deg) configs.push_back({"rotation_bound", v, step, v, thr});
  for (double v : o.thresholds_m) configs.push_back({"threshold", v, step, bound, v});
  std::vector<CodecSweepResult> results;
  for (const Config& c : configs) results.push_back(RunOne(o, c));
  return results;
}

}  // namespace edgephys::loadgen
