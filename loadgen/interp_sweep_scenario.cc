// interp-sweep as a Scenario: options, validation and the report (JSON, table, charts).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <sstream>

#include "loadgen/interp_sweep.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// The JSON of a result: one field per member, named as the member (nlohmann::json sorts keys).
// The interpolator is added by name.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(InterpSweepResult, network, rate_hz, pos_err_max_m,
                                   pos_err_p99_m, pos_err_mean_m, rot_err_max_deg,
                                   rot_err_p99_deg, rot_err_mean_deg, display_delay_ms,
                                   buffer_delay_ms, extrapolated_frac, snapshots_lost_frac, frames)
// The options a report echoes, named as the members (with the motion's, the quantisation's and
// the networks added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(InterpSweepOptions, rates_hz, duration_s, warmup_s, render_hz,
                                   objects, quantize)

namespace {

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

nlohmann::json Json(const InterpSweepOptions& o, const std::vector<InterpSweepResult>& results) {
  nlohmann::json j;
  nlohmann::json nets = nlohmann::json::array();
  for (const auto& n : o.networks) {
    nets.push_back({{"name", n.name},
                    {"latency_ms", n.latency_s * 1000},
                    {"jitter_ms", n.jitter_s * 1000},
                    {"loss", n.loss}});
  }
  j["options"] = o;
  j["options"].update(o.motion);
  j["options"].update({{"position_step_m", o.quantize ? o.position_step_m : 0.0f},
                       {"rotation_bound_deg", o.quantize ? o.rotation_bound_deg : 0.0f},
                       {"networks", nets}});
  j["results"] = nlohmann::json::array();
  for (const auto& r : results) {
    nlohmann::json e = r;
    e["interpolator"] = InterpolatorName(r.interpolator);
    j["results"].push_back(e);
  }
  return j;
}

// One section per network condition.
void FillTable(const InterpSweepOptions&, const std::vector<InterpSweepResult>& results,
               Table* t) {
  std::string network;
  for (const auto& r : results) {
    if (r.network != network) {
      network = r.network;
      t->Text("\n[" + network + "]\n");
      t->Line("%-10s %5s %10s %10s %10s %9s %9s %9s %9s %7s\n", "interp", "Hz", "pos max mm",
              "pos p99 mm", "pos avg mm", "rot max", "rot p99", "delay ms", "buf ms", "extrap");
    }
    t->Line("%-10s %5.0f %10.2f %10.2f %10.2f %9.3f %9.3f %9.1f %9.1f %6.1f%%\n",
            InterpolatorName(r.interpolator), r.rate_hz, r.pos_err_max_m * 1000,
            r.pos_err_p99_m * 1000, r.pos_err_mean_m * 1000, r.rot_err_max_deg, r.rot_err_p99_deg,
            r.display_delay_ms, r.buffer_delay_ms, r.extrapolated_frac * 100);
  }
  t->Text("(rot in degrees; delay = sender sample to screen incl. latency; buf = SnapshotBuffer "
          "delay behind the estimated sender clock; extrap = frames past the newest snapshot)\n");
}

// <prefix>.dat (one index block per (network, interpolator), in first-appearance order) and,
// per network condition, <prefix>_<network>: p99 position error vs send rate, one line per
// interpolator, log y.
ChartSet Charts(const InterpSweepOptions& options, const std::vector<InterpSweepResult>& results,
                const std::string& prefix) {
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
  std::ostringstream dat;
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
  ChartSet set;
  set.data = dat.str();

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
    set.charts.push_back(
        {.stem = prefix + "_" + network, .body = gp.str(), .terminals = chart::LabelTerminals()});
  }
  return set;
}

class InterpSweepScenario final
    : public MeasuringScenario<InterpSweepOptions, std::vector<InterpSweepResult>> {
 public:
  InterpSweepScenario()
      : MeasuringScenario("interp-sweep", "Interpolation error vs send rate (offline)",
                          {Json, FillTable, Charts}, "interp_sweep") {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--rates", rates_, "Send rates in Hz (comma separated)");
    cmd.add_option("--interpolators", methods_, "lerp-slerp,dq-dlb,dq-sclerp,hermite,none");
    AddWindowOptions(cmd, &o_.warmup_s, &o_.duration_s, " per rate and network");
    cmd.add_option("--objects", o_.objects, "Objects (independent streams)");
    cmd.add_option("--render-hz", o_.render_hz, "Receiver frame rate");
    AddMotionOptions(cmd, &o_.motion, "Motion and network seed");
    cmd.add_option("--latency", latency_s_, "Base one-way latency (s), both conditions");
    cmd.add_option("--jitter", jitter_s_, "Impaired condition: uniform +- jitter (s)");
    cmd.add_option("--loss", loss_, "Impaired condition: loss probability");
    cmd.add_flag("--quantize,!--no-quantize", o_.quantize, "Quantise snapshots like state format 2");
    AddQuantisationOptions(cmd, &o_.position_step_m, &o_.rotation_bound_deg);
  }

  std::string Validate() override {
    if (!ParseList(rates_, &o_.rates_hz)) return "--rates: expected a comma-separated list of rates";
    std::string unknown;
    if (!ParseNames(methods_, ParseInterpolator, &o_.interpolators, &unknown)) {
      return "--interpolators: unknown interpolator '" + unknown + "'";
    }
    for (double r : o_.rates_hz) {
      if (r <= 0) return "--rates must be positive";
    }
    if (o_.interpolators.empty() || o_.duration_s <= 0 || o_.warmup_s < 0 || o_.objects == 0 ||
        o_.render_hz <= 0 || latency_s_ < 0 || jitter_s_ < 0 || loss_ < 0 || loss_ >= 1) {
      return "invalid --interpolators, --duration, --warmup, --objects, --render-hz, "
             "--latency, --jitter or --loss";
    }
    char impaired[64];
    std::snprintf(impaired, sizeof(impaired), "loss%g_jitter%g", loss_ * 100, jitter_s_ * 1000);
    o_.networks = {{"clean", latency_s_, 0, 0}, {impaired, latency_s_, jitter_s_, loss_}};
    return "";
  }

  std::optional<std::vector<InterpSweepResult>> Measure() override {
    return NonEmpty(RunInterpSweep(o_));
  }

 private:
  std::string rates_ = "6,12,24,30,48,60";
  std::string methods_ = "lerp-slerp,dq-dlb,dq-sclerp,hermite,none";
  double latency_s_ = 0.030, jitter_s_ = 0.020, loss_ = 0.05;  // the impaired condition
};

}  // namespace

std::unique_ptr<Scenario> MakeInterpSweepScenario() {
  return std::make_unique<InterpSweepScenario>();
}

}  // namespace edgephys::loadgen
