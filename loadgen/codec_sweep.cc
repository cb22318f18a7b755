#include "loadgen/codec_sweep.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "client/interpolation.h"
#include "loadgen/interp_sweep.h"
#include "loadgen/stats.h"
#include "protocol/connection.h"
#include "protocol/delta_codec.h"
#include "protocol/quantize.h"

namespace edgephys::loadgen {
namespace {

// Connection header + unreliable chunk header of one packet (21 bytes).
constexpr size_t kPacketHeaders = kMaxPacketSize - kMaxUnreliablePayload;

// SplitMix64 (platform-independent, like interp_sweep.cc).
class Rng {
 public:
  explicit Rng(uint64_t seed) : state_(seed) {}
  double Uniform() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    z ^= z >> 31;
    return static_cast<double>(z >> 11) * (1.0 / 9007199254740992.0);
  }

 private:
  uint64_t state_;
};

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
  Rng rng(o.motion.seed * 0x9E3779B97F4A7C15ull + 17);

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
        bytes += size + kPacketHeaders;
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

std::string LabelOf(const CodecSweepResult& r) {
  char text[64];
  if (r.dimension == "step") {
    std::snprintf(text, sizeof(text), "%gmm", r.value * 1000);
  } else if (r.dimension == "rotation_bound") {
    std::snprintf(text, sizeof(text), "%gdeg", r.value);
  } else {
    std::snprintf(text, sizeof(text), "thr%gmm", r.value * 1000);
  }
  return text;
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

std::string CodecSweepJson(const CodecSweepOptions& o,
                           const std::vector<CodecSweepResult>& results) {
  nlohmann::json j;
  j["scenario"] = "codec-sweep";
  j["options"] = {{"objects", o.objects},
                  {"rate_hz", o.rate_hz},
                  {"duration_s", o.duration_s},
                  {"warmup_s", o.warmup_s},
                  {"loss", o.loss},
                  {"speed_mps", o.motion.speed_mps},
                  {"spin_dps", o.motion.spin_dps},
                  {"seed", o.motion.seed},
                  {"slow_fraction", o.slow_fraction},
                  {"slow_speed_mps", o.slow_motion.speed_mps},
                  {"slow_spin_dps", o.slow_motion.spin_dps},
                  {"default_position_step_m", o.default_position_step_m},
                  {"default_rotation_bound_deg", o.default_rotation_bound_deg},
                  {"default_threshold_m", o.default_threshold_m},
                  {"rotation_threshold_deg_per_m", o.rotation_threshold_deg_per_m},
                  {"packet_header_bytes", kPacketHeaders},
                  {"max_payload_bytes", kMaxUnreliablePayload}};
  j["results"] = nlohmann::json::array();
  for (const auto& r : results) {
    j["results"].push_back({{"dimension", r.dimension},
                            {"value", r.value},
                            {"position_step_m", r.position_step_m},
                            {"rotation_bound_deg", r.rotation_bound_deg},
                            {"position_threshold_m", r.position_threshold_m},
                            {"rotation_threshold_deg", r.rotation_threshold_deg},
                            {"bytes_per_s_per_receiver", r.bytes_per_s_per_receiver},
                            {"payload_bytes_per_s", r.payload_bytes_per_s},
                            {"packets_per_s", r.packets_per_s},
                            {"updates_per_s", r.updates_per_s},
                            {"bytes_per_update", r.bytes_per_update},
                            {"keyframe_frac", r.keyframe_frac},
                            {"pos_err_max_m", r.pos_err_max_m},
                            {"pos_err_p99_m", r.pos_err_p99_m},
                            {"rot_err_max_deg", r.rot_err_max_deg},
                            {"rot_err_p99_deg", r.rot_err_p99_deg},
                            {"update_pos_err_max_m", r.update_pos_err_max_m},
                            {"update_rot_err_max_deg", r.update_rot_err_max_deg},
                            {"unresolved_references", r.unresolved_references},
                            {"samples", r.samples}});
  }
  return j.dump(2);
}

std::string CodecSweepTable(const std::vector<CodecSweepResult>& results) {
  std::ostringstream out;
  char line[256];
  std::snprintf(line, sizeof(line), "%-14s %9s %8s %8s %9s %9s %8s %7s %6s %8s %8s %8s %8s\n",
                "dimension", "value", "step mm", "bound", "thr mm", "KB/s", "upd/s", "B/upd",
                "key%", "pos max", "pos p99", "rot max", "rot p99");
  out << line;
  for (const auto& r : results) {
    std::snprintf(line, sizeof(line),
                  "%-14s %9s %8.2f %8.3f %9.2f %9.2f %8.1f %7.2f %5.1f%% %8.3f %8.3f %8.4f %8.4f\n",
                  r.dimension.c_str(), LabelOf(r).c_str(), r.position_step_m * 1000,
                  r.rotation_bound_deg, r.position_threshold_m * 1000,
                  r.bytes_per_s_per_receiver / 1000, r.updates_per_s, r.bytes_per_update,
                  r.keyframe_frac * 100, r.pos_err_max_m * 1000, r.pos_err_p99_m * 1000,
                  r.rot_err_max_deg, r.rot_err_p99_deg);
    out << line;
  }
  out << "(KB = 1000 bytes, incl. 21 header bytes per packet; B/upd incl. headers; pos in mm, rot in "
         "deg: the receiver's state of every object at every tick vs the float truth)\n";
  return out.str();
}

bool WriteCodecSweepCharts(const CodecSweepOptions& o, const std::vector<CodecSweepResult>& results,
                           const std::string& prefix) {
  std::ofstream dat(prefix + ".dat");
  if (!dat) return false;
  std::vector<std::string> dimensions;
  for (const auto& r : results) {
    if (std::find(dimensions.begin(), dimensions.end(), r.dimension) == dimensions.end()) {
      dimensions.push_back(r.dimension);
    }
  }
  // The default configuration is in every dimension: label it once (its own last block).
  auto is_default = [&](const CodecSweepResult& r) {
    return r.position_step_m == o.default_position_step_m &&
           r.rotation_bound_deg == o.default_rotation_bound_deg &&
           r.position_threshold_m == o.default_threshold_m;
  };
  auto row = [&](const CodecSweepResult& r, const std::string& label) {
    dat << r.bytes_per_s_per_receiver / 1000 << " " << r.pos_err_max_m * 1000 << " "
        << r.rot_err_max_deg << " " << r.pos_err_p99_m * 1000 << " " << r.rot_err_p99_deg
        << " \"" << label << "\"\n";
  };
  for (const auto& d : dimensions) {
    dat << "# dimension " << d << "\n# kBps pos_max_mm rot_max_deg pos_p99_mm rot_p99_deg label\n";
    for (const auto& r : results) {
      if (r.dimension == d) row(r, is_default(r) ? "" : LabelOf(r));
    }
    dat << "\n\n";
  }
  const CodecSweepResult* default_result = nullptr;
  for (const auto& r : results) {
    if (is_default(r)) default_result = &r;
  }
  if (default_result) {
    dat << "# defaults\n";
    row(*default_result, "defaults");
    dat << "\n\n";
  }
  dat.close();
  if (!dat) return false;
  auto title_of = [](const std::string& d) {
    return d == "step" ? std::string("position step")
           : d == "rotation_bound" ? std::string("rotation bound")
                                   : std::string("selective-sync threshold");
  };
  struct Chart {
    const char* name;
    const char* ylabel;
    int column;
  };
  for (const Chart& c : {Chart{"position", "max position error (mm)", 2},
                         Chart{"rotation", "max rotation error (deg)", 3}}) {
    std::ostringstream gp;
    gp << "set title 'Format 2: bandwidth vs max " << c.name
       << " error (one parameter varied at a time)'\n"
       << "set xlabel 'KB/s per receiver (incl. packet headers)'\nset ylabel '" << c.ylabel
       << "'\nset format y '%g'\nset grid\nset key top right\n"
          "set autoscale fix\nset offsets graph 0.08, graph 0.08, graph 0.15, graph 0.1\nplot ";
    for (size_t i = 0; i < dimensions.size(); ++i) {
      gp << (i ? ", " : "") << "'" << prefix << ".dat' index " << i << " using 1:" << c.column
         << " with linespoints lw 2 pt 7 lc " << i + 1 << " title '" << title_of(dimensions[i])
         << "', '' index " << i << " using 1:" << c.column << ":6 with labels offset char 0,"
         << (i % 2 ? "-1" : "1") << " tc lt " << i + 1 << " notitle";
    }
    if (default_result) {
      gp << ", '' index " << dimensions.size() << " using 1:" << c.column
         << " with points pt 6 ps 2.5 lc rgb 'black' notitle, '' index " << dimensions.size()
         << " using 1:" << c.column << ":6 with labels offset char 0,-1.6 notitle";
    }
    gp << "\n";
    if (!WriteGnuplotChart(prefix, c.name, gp.str())) return false;
  }
  return true;
}

}  // namespace edgephys::loadgen
