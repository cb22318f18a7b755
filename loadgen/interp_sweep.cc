#include "loadgen/interp_sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "client/snapshot_buffer.h"
#include "loadgen/stats.h"
#include "protocol/quantize.h"

namespace edgephys::loadgen {
namespace {

uint64_t Mix(uint64_t a, uint64_t b) {
  SplitMix64 r(a * 0x100000001B3ull ^ (b + 0x632BE59BD9B4E019ull));
  return r.Next();
}

struct Arrival {
  double receive_s;
  Snapshot snapshot;
};

struct Accumulator {
  std::vector<double> pos, rot;
  double pos_sum = 0, rot_sum = 0;
};

}  // namespace

bool ParseInterpolator(const std::string& name, Interpolator* out) {
  std::string n = name;
  std::replace(n.begin(), n.end(), '_', '-');
  if (n == "lerp-slerp") *out = Interpolator::kLerpSlerp;
  else if (n == "dq-dlb") *out = Interpolator::kDualQuatDlb;
  else if (n == "dq-sclerp") *out = Interpolator::kDualQuatSclerp;
  else if (n == "hermite") *out = Interpolator::kHermite;
  else if (n == "none") *out = Interpolator::kNone;
  else return false;
  return true;
}

std::vector<InterpSweepResult> RunInterpSweep(const InterpSweepOptions& o) {
  std::vector<InterpSweepResult> results;
  QuantizationParams qp;
  if (o.quantize) {
    QuantizationConfig qc;
    qc.position_step_m = o.position_step_m;
    qc.rotation_error_deg = o.rotation_bound_deg;
    auto made = MakeQuantizationParams(qc);
    if (!made.ok()) {
      std::fprintf(stderr, "interp-sweep: invalid quantisation settings\n");
      return results;
    }
    qp = *made;
  }
  const double end_s = o.warmup_s + o.duration_s;
  const size_t methods = o.interpolators.size();

  for (size_t ni = 0; ni < o.networks.size(); ++ni) {
    const NetworkCondition& net = o.networks[ni];
    for (double rate : o.rates_hz) {
      std::vector<Accumulator> acc(methods);
      double display_delay_sum = 0, buffer_delay_sum = 0;
      uint64_t frames = 0, extrapolated = 0, sent = 0, lost = 0;
      std::vector<Arrival> arrivals;
      for (uint32_t obj = 0; obj < o.objects; ++obj) {
        const Motion motion(o.motion, obj);
        SplitMix64 rng(Mix(Mix(o.motion.seed, ni), Mix(static_cast<uint64_t>(rate * 1000), obj)));
        // Sender: ticks at the send rate from a random phase; the state is sampled at the ms
        // timestamp that goes on the wire.
        arrivals.clear();
        const double phase = rng.Uniform() / rate;
        for (uint64_t k = 0;; ++k) {
          const double tick = phase + static_cast<double>(k) / rate;
          if (tick > end_s) break;
          const double t = std::floor(tick * 1000.0) / 1000.0;
          EntityState s = motion.At(t);
          if (o.quantize) {
            QuantizedState q;
            (void)QuantizeState(qp, s, &q);
            s.position = DequantizePosition(qp, q.position);
            s.rotation = DequantizeRotation(qp, q.rotation);
          }
          ++sent;
          // Draw both numbers for every snapshot so that loss does not shift the jitter
          // sequence (the same arrivals with or without loss, apart from the lost ones).
          const double u_loss = rng.Uniform();
          const double u_jitter = rng.Uniform();
          if (u_loss < net.loss) {
            ++lost;
            continue;
          }
          const double delay = std::max(0.0, net.latency_s + (2 * u_jitter - 1) * net.jitter_s);
          Snapshot snap;
          snap.sender_time_s = t;
          snap.position = s.position;
          snap.rotation = s.rotation;
          arrivals.push_back({t + delay, snap});
        }
        std::stable_sort(arrivals.begin(), arrivals.end(),
                         [](const Arrival& a, const Arrival& b) { return a.receive_s < b.receive_s; });

        // Receiver: one buffer, rendered at render_hz from a random frame phase.
        SnapshotBuffer buffer;
        size_t next = 0;
        const double frame_phase = rng.Uniform() / o.render_hz;
        for (uint64_t f = 0;; ++f) {
          const double now = frame_phase + static_cast<double>(f) / o.render_hz;
          if (now > end_s) break;
          while (next < arrivals.size() && arrivals[next].receive_s <= now) {
            (void)buffer.Insert(arrivals[next].snapshot, arrivals[next].receive_s);
            ++next;
          }
          if (buffer.empty()) continue;
          const double render_time = buffer.RenderTime(now);
          if (now < o.warmup_s) continue;
          const EntityState truth = motion.At(render_time);
          const Pose truth_pose{truth.position, truth.rotation};
          for (size_t m = 0; m < methods; ++m) {
            const Pose pose = Sample(buffer, render_time, o.interpolators[m]);
            const PoseError e = Compare(pose, truth_pose);
            acc[m].pos.push_back(e.pos_m);
            acc[m].rot.push_back(e.rot_deg);
            acc[m].pos_sum += e.pos_m;
            acc[m].rot_sum += e.rot_deg;
          }
          ++frames;
          display_delay_sum += now - render_time;
          buffer_delay_sum += buffer.current_delay_s();
          if (render_time > buffer.newest().sender_time_s) ++extrapolated;
        }
      }
      for (size_t m = 0; m < methods; ++m) {
        InterpSweepResult r;
        r.network = net.name;
        r.rate_hz = rate;
        r.interpolator = o.interpolators[m];
        const double n = frames > 0 ? static_cast<double>(frames) : 1.0;
        r.pos_err_max_m = Max(acc[m].pos);
        r.pos_err_p99_m = Percentile(acc[m].pos, 99);
        r.pos_err_mean_m = acc[m].pos_sum / n;
        r.rot_err_max_deg = Max(acc[m].rot);
        r.rot_err_p99_deg = Percentile(acc[m].rot, 99);
        r.rot_err_mean_deg = acc[m].rot_sum / n;
        r.display_delay_ms = display_delay_sum / n * 1000;
        r.buffer_delay_ms = buffer_delay_sum / n * 1000;
        r.extrapolated_frac = static_cast<double>(extrapolated) / n;
        r.snapshots_lost_frac = sent > 0 ? static_cast<double>(lost) / static_cast<double>(sent) : 0;
        r.frames = frames;
        results.push_back(r);
      }
    }
  }
  return results;
}

}  // namespace edgephys::loadgen
