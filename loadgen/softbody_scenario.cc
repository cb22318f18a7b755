// softbody as a Scenario: options, validation and the report (JSON, table, charts).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <sstream>

#include "loadgen/scenario.h"
#include "loadgen/softbody.h"

namespace edgephys::loadgen {

// The JSON of a result: one field per member, named as the member (nlohmann::json sorts keys).
// The options a report echoes, named as the members (with the particle target, the relay's tick
// rate and mode added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(SoftBodyOptions, poke_period_s, bench_warmup_steps, bench_steps,
                                   receivers, duration_s, relay_settle_steps, position_step_m,
                                   soft_touched_hz)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(SoftBodyResult, bunnies, particles, step_ms_median,
                                   step_ms_p99, bench_steps, relay_ok,
                                   egress_mbit_per_s_per_client, socket_mbit_per_s_per_client,
                                   ip_udp_mbit_per_s_per_client,
                                   paper_mbit_per_s, soft_updates_per_s_per_client,
                                   relay_step_ms_mean, sim_speed, deformation_min_m,
                                   deformation_max_m, node_err_max_m, node_err_p99_m,
                                   node_err_sent_max_m, node_err_sent_p99_m, error_samples)

namespace {

nlohmann::json Json(const SoftBodyOptions& o, const std::vector<SoftBodyResult>& results) {
  nlohmann::json j = {{"options", o}};
  j["options"].update(
      {{"particles_per_bunny_target", o.particles}, {"tick_rate_hz", 60}, {"mode", "edgephys"}});
  j["relay"] = {{"external", o.external.enabled()}};
  if (o.external.enabled()) j["relay"].update({{"relay", o.external.relay}, {"metrics", o.external.metrics}});
  j["results"] = nlohmann::json::array();
  for (const auto& r : results) {
    nlohmann::json e = r;
    e["egress_ratio_to_paper"] = RatioOr0(r.egress_mbit_per_s_per_client, r.paper_mbit_per_s);
    j["results"].push_back(e);
  }
  return j;
}

void FillTable(const SoftBodyOptions&, const std::vector<SoftBodyResult>& results, Table* t) {
  t->Line("%7s %9s | %8s %8s | %8s %5s %7s %6s %6s %7s %11s %8s %8s %8s\n", "bunnies",
          "particles", "PhyS med", "PhyS p99", "relay ms", "sim x", "Mb/s", "paper", "ratio",
          "chunk/s", "deform mm", "err max", "err p99", "sent max");
  for (const auto& r : results) {
    char deform[32];
    std::snprintf(deform, sizeof(deform), "%.0f-%.0f", r.deformation_min_m * 1000,
                  r.deformation_max_m * 1000);
    t->Line("%7u %9u | %8.2f %8.2f | %8.2f %5.2f %7.3f %6.2f %6.3f %7.1f %11s %8.2f %8.2f %8.3f\n",
            r.bunnies, r.particles, r.step_ms_median, r.step_ms_p99, r.relay_step_ms_mean,
            r.sim_speed, r.egress_mbit_per_s_per_client, r.paper_mbit_per_s,
            RatioOr0(r.egress_mbit_per_s_per_client, r.paper_mbit_per_s),
            r.soft_updates_per_s_per_client, deform, r.node_err_max_m * 1000,
            r.node_err_p99_m * 1000, r.node_err_sent_max_m * 1000);
  }
  t->Text("(PhyS med/p99: standalone step ms; relay ms: relay's mean PhyS step; Mb/s: relay egress per\n"
          " receiver, 10^6 bit/s; paper: Bunny_N; deform: bunny 0's largest spring length change from\n"
          " rest, min-max over the window; err: receiver's particles vs the relay's at the same moment,\n"
          " max over particles (mm); sent max: vs the particles the relay sent (mm))\n");
}

// <prefix>.dat, <prefix>_egress and <prefix>_steptime (clustered histograms per bunny count).
ChartSet Charts(const SoftBodyOptions&, const std::vector<SoftBodyResult>& results,
                const std::string& prefix) {
  std::ostringstream dat;
  dat << "# bunnies mbit paper_mbit step_med step_p99 relay_step_ms err_max_mm sent_max_mm\n";
  for (const auto& r : results) {
    dat << r.bunnies << " " << r.egress_mbit_per_s_per_client << " " << r.paper_mbit_per_s << " "
        << r.step_ms_median << " " << r.step_ms_p99 << " " << r.relay_step_ms_mean << " "
        << r.node_err_max_m * 1000 << " " << r.node_err_sent_max_m * 1000 << "\n";
  }
  const std::string d = "'" + prefix + ".dat'";
  // Both charts: one cluster of bars per bunny count.
  const char* xlabel = "set xlabel 'bunnies (~500 particles each)'\n";
  const char* style =
      "set grid\nset key top left\nset style data histograms\n"
      "set style histogram clustered gap 1\nset style fill solid 0.7 border -1\n"
      "set yrange [0:*]\n";
  std::ostringstream eg;
  eg << "set title 'Soft bodies: PhyS egress per client vs the paper (1 mm particle step)'\n"
     << xlabel << "set ylabel 'Mb/s per client'\n" << style
     << "plot " << d << " using 2:xtic(1) title 'edgephys (measured)', "
     << d << " using ($3>0?$3:1/0):xtic(1) title 'paper'\n";
  std::ostringstream st;
  st << "set title 'Soft bodies: PhyS step time'\n"
     << xlabel << "set ylabel 'ms per step'\n" << style
     << "plot " << d << " using 4:xtic(1) title 'median (standalone)', "
     << d << " using 5:xtic(1) title 'p99 (standalone)', "
     << d << " using 6:xtic(1) title 'relay mean'\n";
  return {dat.str(),
          {{.stem = prefix + "_egress", .body = eg.str()},
           {.stem = prefix + "_steptime", .body = st.str()}}};
}

class SoftBodyScenario final
    : public MeasuringScenario<SoftBodyOptions, std::vector<SoftBodyResult>> {
 public:
  SoftBodyScenario()
      : MeasuringScenario("softbody", "PhyS soft bodies: egress vs the paper, step time, error",
                          {Json, FillTable, Charts}, "softbody") {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--bunnies", bunnies_, "Bunny counts (comma separated)");
    cmd.add_option("--particles", o_.particles, "Target particles per bunny");
    AddSceneRelayRunOptions(cmd, &o_.duration_s, &o_.receivers, &o_.relay_settle_steps,
                            "bunny count");
    cmd.add_option("--poke-period", o_.poke_period_s, "Seconds per poke");
    AddStandaloneStepOptions(cmd, &o_.bench_warmup_steps, &o_.bench_steps);
    cmd.add_option("--position-step", o_.position_step_m, "edgephys quantisation step (m)");
    AddExternalRelayOptions(cmd, &o_.external);
    cmd.add_option("--soft-touched-hz", o_.soft_touched_hz,
                   "Relay's send rate of a touched soft body (0: its default, 24)");
  }

  std::string Validate() override {
    if (!ParseList(bunnies_, &o_.bunnies)) return "--bunnies: expected a comma-separated list of counts";
    for (uint32_t n : o_.bunnies) {
      if (n == 0 || n > 64) return "--bunnies: counts must be in 1..64";
    }
    if (o_.duration_s <= 0 || o_.receivers == 0 || o_.particles < 10 || o_.poke_period_s <= 0 ||
        o_.bench_steps <= 0 || o_.soft_touched_hz < 0 || o_.soft_touched_hz > 240) {
      return "invalid --duration, --receivers, --particles, --poke-period, --bench-steps or "
             "--soft-touched-hz";
    }
    return ValidateExternalRelay(o_.external);
  }

  std::optional<std::vector<SoftBodyResult>> Measure() override { return RunSoftBody(o_); }

  bool Succeeded(const std::vector<SoftBodyResult>& results) const override {
    return AllRelayRunsOk(results);
  }

 private:
  std::string bunnies_ = "1,3";
};

}  // namespace

std::unique_ptr<Scenario> MakeSoftBodyScenario() { return std::make_unique<SoftBodyScenario>(); }

}  // namespace edgephys::loadgen
