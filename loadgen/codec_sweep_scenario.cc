// codec-sweep as a Scenario: options, validation and the report (JSON, table, charts).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <sstream>

#include "loadgen/codec_sweep.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// The JSON of a result: one field per member, named as the member (nlohmann::json sorts keys).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CodecSweepResult, dimension, value, position_step_m,
                                   rotation_bound_deg, position_threshold_m,
                                   rotation_threshold_deg, bytes_per_s_per_receiver,
                                   payload_bytes_per_s, packets_per_s, updates_per_s,
                                   bytes_per_update, keyframe_frac, pos_err_max_m, pos_err_p99_m,
                                   rot_err_max_deg, rot_err_p99_deg, update_pos_err_max_m,
                                   update_rot_err_max_deg, unresolved_references, samples)

// The options a report echoes, named as the members (with the motion's, the slow motion's
// speed and spin and the packet sizes added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CodecSweepOptions, objects, rate_hz, duration_s, warmup_s, loss,
                                   slow_fraction, default_position_step_m,
                                   default_rotation_bound_deg, default_threshold_m,
                                   rotation_threshold_deg_per_m)

namespace {

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

nlohmann::json Json(const CodecSweepOptions& o, const std::vector<CodecSweepResult>& results) {
  nlohmann::json j = {{"options", o}};
  j["options"].update(o.motion);
  j["options"].update({{"slow_speed_mps", o.slow_motion.speed_mps},
                       {"slow_spin_dps", o.slow_motion.spin_dps},
                       {"packet_header_bytes", kPacketHeaderBytes},
                       {"max_payload_bytes", kMaxUnreliablePayload}});
  j["results"] = results;
  return j;
}

void FillTable(const CodecSweepOptions&, const std::vector<CodecSweepResult>& results,
               Table* t) {
  t->Line("%-14s %9s %8s %8s %9s %9s %8s %7s %6s %8s %8s %8s %8s\n", "dimension", "value",
          "step mm", "bound", "thr mm", "KB/s", "upd/s", "B/upd", "key%", "pos max", "pos p99",
          "rot max", "rot p99");
  for (const auto& r : results) {
    t->Line("%-14s %9s %8.2f %8.3f %9.2f %9.2f %8.1f %7.2f %5.1f%% %8.3f %8.3f %8.4f %8.4f\n",
            r.dimension.c_str(), LabelOf(r).c_str(), r.position_step_m * 1000,
            r.rotation_bound_deg, r.position_threshold_m * 1000, r.bytes_per_s_per_receiver / 1000,
            r.updates_per_s, r.bytes_per_update, r.keyframe_frac * 100, r.pos_err_max_m * 1000,
            r.pos_err_p99_m * 1000, r.rot_err_max_deg, r.rot_err_p99_deg);
  }
  t->Text("(KB = 1000 bytes, incl. 21 header bytes per packet; B/upd incl. headers; pos in mm, "
          "rot in deg: the receiver's state of every object at every tick vs the float truth)\n");
}

// <prefix>.dat and <prefix>_position / <prefix>_rotation: bandwidth vs max error, one series
// per swept dimension, points labelled by the value, the default configuration circled once.
ChartSet Charts(const CodecSweepOptions& o, const std::vector<CodecSweepResult>& results,
                const std::string& prefix) {
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
  std::ostringstream dat;
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
  ChartSet set;
  set.data = dat.str();
  auto title_of = [](const std::string& d) {
    return d == "step" ? std::string("position step")
           : d == "rotation_bound" ? std::string("rotation bound")
                                   : std::string("selective-sync threshold");
  };
  struct Plot {
    const char* name;
    const char* ylabel;
    int column;
  };
  for (const Plot& c : {Plot{"position", "max position error (mm)", 2},
                        Plot{"rotation", "max rotation error (deg)", 3}}) {
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
    set.charts.push_back({.stem = prefix + "_" + c.name,
                          .body = gp.str(),
                          .terminals = chart::LabelTerminals()});
  }
  return set;
}

class CodecSweepScenario final
    : public MeasuringScenario<CodecSweepOptions, std::vector<CodecSweepResult>> {
 public:
  CodecSweepScenario()
      : MeasuringScenario("codec-sweep", "Quantized delta codec: bandwidth vs accuracy (offline)",
                          {Json, FillTable, Charts}, "codec_sweep") {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--steps", steps_, "Position steps (m) to sweep");
    cmd.add_option("--rotation-bounds", bounds_, "Rotation bounds (deg) to sweep");
    cmd.add_option("--thresholds", thresholds_, "Selective-sync position thresholds (m) to sweep");
    cmd.add_option("--position-step", o_.default_position_step_m, "Default step (m)");
    cmd.add_option("--rotation-bound", o_.default_rotation_bound_deg,
                   "Default rotation bound (deg)");
    cmd.add_option("--threshold", o_.default_threshold_m, "Default position threshold (m)");
    cmd.add_option("--rotation-threshold-per-m", o_.rotation_threshold_deg_per_m,
                   "Rotation threshold (deg) per metre of position threshold");
    cmd.add_option("--objects", o_.objects, "Objects");
    cmd.add_option("--rate", o_.rate_hz, "Sends per second per object");
    cmd.add_option("--duration", o_.duration_s, "Seconds per configuration");
    cmd.add_option("--slow-fraction", o_.slow_fraction,
                   "Fraction of objects that only creep (where thresholds matter)");
    cmd.add_option("--slow-speed", o_.slow_motion.speed_mps, "Creeping objects' speed (m/s)");
    cmd.add_option("--slow-spin", o_.slow_motion.spin_dps, "Creeping objects' spin (deg/s)");
    AddMotionOptions(cmd, &o_.motion, "Motion and loss seed");
    cmd.add_option("--loss", o_.loss, "Packet loss probability");
  }

  std::string Validate() override {
    if (!ParseList(steps_, &o_.steps_m) || !ParseList(bounds_, &o_.rotation_bounds_deg) ||
        !ParseList(thresholds_, &o_.thresholds_m)) {
      return "--steps, --rotation-bounds, --thresholds: expected comma-separated numbers";
    }
    if (o_.objects == 0 || o_.rate_hz <= 0 || o_.duration_s <= 0 || o_.loss < 0 || o_.loss >= 1 ||
        o_.slow_fraction < 0 || o_.slow_fraction > 1) {
      return "invalid --objects, --rate, --duration, --loss or --slow-fraction";
    }
    return "";
  }

  std::optional<std::vector<CodecSweepResult>> Measure() override {
    return NonEmpty(RunCodecSweep(o_));
  }

 private:
  std::string steps_ = "0.0005,0.001,0.002,0.005", bounds_ = "0.05,0.1,0.2,0.5";
  std::string thresholds_ = "0,0.0005,0.001,0.005";
};

}  // namespace

std::unique_ptr<Scenario> MakeCodecSweepScenario() { return std::make_unique<CodecSweepScenario>(); }

}  // namespace edgephys::loadgen
