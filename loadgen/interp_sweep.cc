#include "loadgen/interp_sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "client/snapshot_buffer.h"
#include "loadgen/stats.h"
#include "protocol/quantize.h"

namespace edgephys::loadgen {
namespace {

// SplitMix64: a tiny, fully specified generator, so runs are identical on every platform
// (std::uniform_real_distribution is implementation-defined).
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  uint64_t Next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  // Uniform in [0, 1).
  double Uniform() { return static_cast<double>(Next() >> 11) * (1.0 / 9007199254740992.0); }

 private:
  uint64_t state_;
};

uint64_t Mix(uint64_t a, uint64_t b) {
  Rng r(a * 0x100000001B3ull ^ (b + 0x632BE59BD9B4E019ull));
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

std::string NetworkTitle(const NetworkCondition& n) {
  char text[160];
  if (n.loss <= 0 && n.jitter_s <= 0) {
    std::snprintf(text, sizeof(text), "%s: %.0f ms latency, no loss, no jitter", n.name.c_str(),
                  n.latency_s * 1000);
  } else {
    std::snprintf(text, sizeof(text), "%s: %.0f ms latency, %.0f%% loss, +-%.0f ms jitter",
                  n.name.c_str(), n.latency_s * 1000, n.loss * 100, n.jitter_s * 1000);
  }
  return text;
}

// Fixed colours / markers per interpolator, so the charts of all networks match; the two
// dual-quaternion methods nearly coincide, so ScLERP is dashed with open markers.
const char* StyleOf(Interpolator m) {
  switch (m) {
    case Interpolator::kLerpSlerp: return "lc rgb '#1f77b4' pt 7";
    case Interpolator::kDualQuatDlb: return "lc rgb '#2ca02c' pt 5";
    case Interpolator::kDualQuatSclerp: return "lc rgb '#d62728' pt 4 dt 2";
    case Interpolator::kHermite: return "lc rgb '#ff7f0e' pt 9";
    case Interpolator::kNone: return "lc rgb '#7f7f7f' pt 13";
  }
  return "";
}

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
        Rng rng(Mix(Mix(o.motion.seed, ni), Mix(static_cast<uint64_t>(rate * 1000), obj)));
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

std::string InterpSweepJson(const InterpSweepOptions& o,
                            const std::vector<InterpSweepResult>& results) {
  nlohmann::json j;
  j["scenario"] = "interp-sweep";
  nlohmann::json nets = nlohmann::json::array();
  for (const auto& n : o.networks) {
    nets.push_back({{"name", n.name},
                    {"latency_ms", n.latency_s * 1000},
                    {"jitter_ms", n.jitter_s * 1000},
                    {"loss", n.loss}});
  }
  j["options"] = {{"rates_hz", o.rates_hz},
                  {"duration_s", o.duration_s},
                  {"warmup_s", o.warmup_s},
                  {"render_hz", o.render_hz},
                  {"objects", o.objects},
                  {"speed_mps", o.motion.speed_mps},
                  {"spin_dps", o.motion.spin_dps},
                  {"seed", o.motion.seed},
                  {"quantize", o.quantize},
                  {"position_step_m", o.quantize ? o.position_step_m : 0.0f},
                  {"rotation_bound_deg", o.quantize ? o.rotation_bound_deg : 0.0f},
                  {"networks", nets}};
  j["results"] = nlohmann::json::array();
  for (const auto& r : results) {
    j["results"].push_back({{"network", r.network},
                            {"rate_hz", r.rate_hz},
                            {"interpolator", InterpolatorName(r.interpolator)},
                            {"pos_err_max_m", r.pos_err_max_m},
                            {"pos_err_p99_m", r.pos_err_p99_m},
                            {"pos_err_mean_m", r.pos_err_mean_m},
                            {"rot_err_max_deg", r.rot_err_max_deg},
                            {"rot_err_p99_deg", r.rot_err_p99_deg},
                            {"rot_err_mean_deg", r.rot_err_mean_deg},
                            {"display_delay_ms", r.display_delay_ms},
                            {"buffer_delay_ms", r.buffer_delay_ms},
                            {"extrapolated_frac", r.extrapolated_frac},
                            {"snapshots_lost_frac", r.snapshots_lost_frac},
                            {"frames", r.frames}});
  }
  return j.dump(2);
}

std::string InterpSweepTable(const std::vector<InterpSweepResult>& results) {
  std::ostringstream out;
  char line[256];
  std::string network;
  for (const auto& r : results) {
    if (r.network != network) {
      network = r.network;
      out << "\n[" << network << "]\n";
      std::snprintf(line, sizeof(line), "%-10s %5s %10s %10s %10s %9s %9s %9s %9s %7s\n",
                    "interp", "Hz", "pos max mm", "pos p99 mm", "pos avg mm", "rot max", "rot p99",
                    "delay ms", "buf ms", "extrap");
      out << line;
    }
    std::snprintf(line, sizeof(line),
                  "%-10s %5.0f %10.2f %10.2f %10.2f %9.3f %9.3f %9.1f %9.1f %6.1f%%\n",
                  InterpolatorName(r.interpolator), r.rate_hz, r.pos_err_max_m * 1000,
                  r.pos_err_p99_m * 1000, r.pos_err_mean_m * 1000, r.rot_err_max_deg,
                  r.rot_err_p99_deg, r.display_delay_ms, r.buffer_delay_ms,
                  r.extrapolated_frac * 100);
    out << line;
  }
  out << "(rot in degrees; delay = sender sample to screen incl. latency; buf = SnapshotBuffer "
         "delay behind the estimated sender clock; extrap = frames past the newest snapshot)\n";
  return out.str();
}

bool WriteGnuplotChart(const std::string& prefix, const std::string& name,
                       const std::string& body, int width, int height) {
  const bool have_gnuplot = std::system("command -v gnuplot >/dev/null 2>&1") == 0;
  const std::string size = std::to_string(width) + "," + std::to_string(height);
  for (const std::string ext : {".png", ".svg"}) {
    const std::string out = prefix + "_" + name + ext;
    const std::string script = out + ".gp";
    const std::string terminal = ext == ".png"
                                     ? "pngcairo noenhanced size " + size + " font 'sans,10'"
                                     : "svg noenhanced size " + size +
                                           " font 'sans,11' background '#ffffff'";
    {
      std::ofstream gp(script);
      if (!gp) return false;
      gp << "set terminal " << terminal << "\nset output '" << out << "'\n" << body;
    }
    if (!have_gnuplot) continue;
    const std::string cmd = "gnuplot '" + script + "' 2>/dev/null";
    if (std::system(cmd.c_str()) != 0 && ext == ".png") {
      // No cairo: plain png terminal.
      std::ofstream gp(script);
      gp << "set terminal png noenhanced size " << size << "\nset output '" << out << "'\n" << body;
      gp.close();
      (void)std::system(cmd.c_str());
    }
  }
  return true;
}

bool WriteInterpSweepCharts(const InterpSweepOptions& options,
                            const std::vector<InterpSweepResult>& results,
                            const std::string& prefix) {
  std::ofstream dat(prefix + ".dat");
  if (!dat) return false;
  // One gnuplot index block per (network, interpolator), in first-appearance order.
  struct Block {
    std::string network;
    Interpolator method;
  };
  std::vector<Block> blocks;
  for (const auto& r : results) {
    bool seen = false;
    for (const auto& b : blocks) seen = seen || (b.network == r.network && b.method == r.interpolator);
    if (!seen) blocks.push_back({r.network, r.interpolator});
  }
  for (const auto& b : blocks) {
    dat << "# network " << b.network << " interpolator " << InterpolatorName(b.method)
        << "\n# rate_hz pos_p99_mm pos_max_mm pos_mean_mm rot_p99_deg\n";
    for (const auto& r : results) {
      if (r.network != b.network || r.interpolator != b.method) continue;
      dat << r.rate_hz << " " << r.pos_err_p99_m * 1000 << " " << r.pos_err_max_m * 1000 << " "
          << r.pos_err_mean_m * 1000 << " " << r.rot_err_p99_deg << "\n";
    }
    dat << "\n\n";
  }
  dat.close();
  if (!dat) return false;

  std::vector<std::string> networks;
  for (const auto& b : blocks) {
    if (std::find(networks.begin(), networks.end(), b.network) == networks.end()) {
      networks.push_back(b.network);
    }
  }
  for (const auto& network : networks) {
    std::string title = network;
    for (const auto& n : options.networks) {
      if (n.name == network) title = NetworkTitle(n);
    }
    std::ostringstream gp;
    gp << "set title 'Interpolated p99 position error vs send rate (" << title << ")'\n"
       << "set xlabel 'send rate (Hz)'\nset ylabel 'p99 position error (mm)'\n"
       << "set logscale y\nset grid\nset key top right\nset xrange [0:*]\n"
       << "set format y '%g'\nplot ";
    bool first = true;
    for (size_t i = 0; i < blocks.size(); ++i) {
      if (blocks[i].network != network) continue;
      gp << (first ? "" : ", ") << "'" << prefix << ".dat' index " << i
         << " using 1:2 with linespoints lw 2 " << StyleOf(blocks[i].method) << " title '"
         << InterpolatorName(blocks[i].method) << "'";
      first = false;
    }
    gp << "\n";
    if (!WriteGnuplotChart(prefix, network, gp.str())) return false;
  }
  return true;
}

}  // namespace edgephys::loadgen
