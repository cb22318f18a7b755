// multiobject as a Scenario: options, validation and the report (JSON, table, charts).
#include <CLI/CLI.hpp>
#include <algorithm>
#include <sstream>

#include "loadgen/multiobject.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// The options a report echoes, named as the members (with the relay's tick rate and mode
// added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(MultiObjectOptions, seed, stirrer_angular_speed, stirrer_reach,
                                   stirrer_center_y, layers, position_threshold_m,
                                   rotation_threshold_deg, stirrer_half_height, sleep_threshold,
                                   moving_speed_mps, bench_warmup_steps, bench_steps, bench_max_s,
                                   receivers, duration_s, relay_settle_steps, relay_max_substeps,
                                   position_step_m, rotation_bound_deg, ambient_hz, shared_encoding,
                                   playout_min_delay_s, playout_limit_s)

namespace {

// Options echoed; per size the standalone figures if they ran, the relay figures if it ran.
nlohmann::json Json(const MultiObjectOptions& o, const std::vector<MultiObjectResult>& results) {
  nlohmann::json j = {{"options", o}};
  j["options"].update({{"tick_rate_hz", 60}, {"mode", "edgephys"}});
  if (o.external.enabled()) {
    j["relay"] = {{"external", true},
                  {"relay", o.external.relay},
                  {"metrics", o.external.metrics},
                  {"cpu_source", o.external.relay_pid > 0
                                     ? "/proc/" + std::to_string(o.external.relay_pid)
                                     : std::string("unknown")}};
  } else {
    j["relay"] = {{"external", false}};
  }
  j["results"] = nlohmann::json::array();
  for (const auto& r : results) {
    nlohmann::json e = {{"objects", r.objects}};
    if (o.bench) {
      e.update({{"step_ms_median", r.step_ms_median},
                {"step_ms_p99", r.step_ms_p99},
                {"raw_bullet_step_ms_median", r.raw_bullet_step_ms_median},
                {"raw_bullet_step_ms_p99", r.raw_bullet_step_ms_p99},
                {"step_ratio_phys_to_raw", r.step_ratio},
                {"bench_steps", r.bench_steps},
                {"realtime_60hz", r.step_ms_median <= 1000.0 / 60.0},
                {"moving_fraction", r.moving_fraction},
                {"moving_fraction_min", r.moving_fraction_min},
                {"raw_moving_fraction", r.raw_moving_fraction},
                {"raw_moving_fraction_min", r.raw_moving_fraction_min}});
    }
    if (o.relay) {
      e.update({{"relay_ok", r.relay_ok},
                {"egress_mbit_per_s_per_client", r.egress_mbit_per_s_per_client},
                {"socket_mbit_per_s_per_client", r.socket_mbit_per_s_per_client},
                {"ip_udp_mbit_per_s_per_client", r.ip_udp_mbit_per_s_per_client},
                {"paper_mbit_per_s", r.paper_mbit_per_s},
                {"egress_ratio_to_paper",
                 RatioOr0(r.egress_mbit_per_s_per_client, r.paper_mbit_per_s)},
                {"updates_per_s_per_client", r.updates_per_s_per_client},
                {"bytes_per_update", r.bytes_per_update},
                {"state_mbit_per_s_per_client", r.state_mbit_per_s_per_client},
                {"events_per_s_per_client", r.events_per_s_per_client},
                {"relay_step_ms_mean", r.relay_step_ms_mean},
                {"sim_speed", r.sim_speed},
                {"relay_moving_fraction", r.relay_moving_fraction},
                {"relay_moving_fraction_min", r.relay_moving_fraction_min},
                {"pos_err_max_m", r.pos_err_max_m},
                {"pos_err_p99_m", r.pos_err_p99_m},
                {"pos_err_sent_max_m", r.pos_err_sent_max_m},
                {"pos_err_sent_p99_m", r.pos_err_sent_p99_m},
                {"error_samples", r.error_samples},
                {"display_err_p50_m", r.display_err_p50_m},
                {"display_err_p99_m", r.display_err_p99_m},
                {"display_err_state_p50_m", r.display_err_state_p50_m},
                {"display_err_state_p99_m", r.display_err_state_p99_m},
                {"display_err_hermite_p50_m", r.display_err_hermite_p50_m},
                {"display_err_hermite_p99_m", r.display_err_hermite_p99_m},
                {"display_err_adaptive_p50_m", r.display_err_adaptive_p50_m},
                {"display_err_adaptive_p99_m", r.display_err_adaptive_p99_m},
                {"display_adaptive_playout_ms_median", r.display_adaptive_playout_ms_median},
                {"display_delay_ms_median", r.display_delay_ms_median},
                {"display_playout_ms_median", r.display_playout_ms_median},
                {"display_rot_err_p50_deg", r.display_rot_err_p50_deg},
                {"display_rot_err_p99_deg", r.display_rot_err_p99_deg},
                {"display_samples", r.display_samples},
                {"spawn_s", r.spawn_s}});
      if (o.external.enabled()) e["relay_cpu_cores"] = r.external_cpu_cores;
    }
    j["results"].push_back(e);
  }
  return j;
}

void FillTable(const MultiObjectOptions&, const std::vector<MultiObjectResult>& results,
               Table* t) {
  t->Line("%7s | %8s %8s %8s %8s %6s %6s | %7s %5s %7s %6s %6s %7s %7s %7s %6s %6s %8s %8s %8s "
          "%8s %8s\n",
          "objects", "PhyS med", "PhyS p99", "raw med", "raw p99", "ratio", "moving", "relay ms",
          "sim x", "Mb/s", "paper", "ratio", "state", "upd/s", "ev/s", "B/upd", "moving",
          "err max", "err p99", "sent max", "disp p50", "disp p99");
  for (const auto& r : results) {
    t->Line("%7u | %8.2f %8.2f %8.2f %8.2f %6.3f %6.2f | %8.2f %5.2f %7.3f %6.2f %6.3f %7.3f "
            "%7.0f %7.0f %6.2f %6.2f %8.2f %8.2f %8.3f %8.2f %8.2f\n",
            r.objects, r.step_ms_median, r.step_ms_p99, r.raw_bullet_step_ms_median,
            r.raw_bullet_step_ms_p99, r.step_ratio, r.moving_fraction, r.relay_step_ms_mean,
            r.sim_speed, r.egress_mbit_per_s_per_client, r.paper_mbit_per_s,
            RatioOr0(r.egress_mbit_per_s_per_client, r.paper_mbit_per_s),
            r.state_mbit_per_s_per_client, r.updates_per_s_per_client, r.events_per_s_per_client,
            r.bytes_per_update, r.relay_moving_fraction, r.pos_err_max_m * 1000,
            r.pos_err_p99_m * 1000, r.pos_err_sent_max_m * 1000, r.display_err_p50_m * 1000,
            r.display_err_p99_m * 1000);
  }
  t->Text("(standalone, same run, interleaved: PhyS/raw step ms median & p99, ratio of medians,\n"
          " moving = share of boxes > 1 cm/s; relay run: relay ms = relay's mean PhyS step, sim x =\n"
          " simulated s per wall s, Mb/s = relay egress per receiver (10^6 bit/s), paper = Obj_N,\n"
          " state = state payload Mb/s within it, ev/s = physics events received per receiver,\n"
          " err = receiver's latest vs relay's state at the same moment (mm), sent max = vs the\n"
          " relay state it was sent from (mm), disp = what receiver 0 displays (jitter buffer,\n"
          " lerp) vs the relay's state at the displayed time (mm))\n");
}

// <prefix>.dat and <prefix>_steptime, _egress, _error.
ChartSet Charts(const MultiObjectOptions&, const std::vector<MultiObjectResult>& results,
                const std::string& prefix) {
  std::ostringstream dat;
  dat << "# objects phys_med phys_p99 raw_med raw_p99 mbit paper_mbit paper_fifth err_max_mm "
         "err_p99_mm sent_max_mm relay_step_ms\n";
  for (const auto& r : results) {
    dat << r.objects << " " << r.step_ms_median << " " << r.step_ms_p99 << " "
        << r.raw_bullet_step_ms_median << " " << r.raw_bullet_step_ms_p99 << " "
        << r.egress_mbit_per_s_per_client << " " << r.paper_mbit_per_s << " "
        << r.paper_mbit_per_s / 5 << " " << r.pos_err_max_m * 1000 << " "
        << r.pos_err_p99_m * 1000 << " " << r.pos_err_sent_max_m * 1000 << " "
        << r.relay_step_ms_mean << "\n";
  }
  const std::string d = "'" + prefix + ".dat'";
  std::ostringstream st;
  st << "set title 'MultiObject: PhyS step time vs raw Bullet (same scene, same run)'\n"
        "set xlabel 'objects'\nset ylabel 'ms per step'\nset logscale xy\nset grid\n"
        "set key top left\n"
        "plot " << d << " using 1:2 with linespoints lw 2 title 'PhyS median', "
     << d << " using 1:3 with linespoints dt 2 title 'PhyS p99', "
     << d << " using 1:4 with linespoints lw 2 title 'raw Bullet median', "
     << d << " using 1:5 with linespoints dt 2 title 'raw Bullet p99', "
     << "16.667 with lines lc rgb 'gray' title '60 Hz budget (16.7 ms)'\n";
  std::ostringstream eg;
  eg << "set title 'MultiObject: PhyS egress per client vs the paper (1 mm / 0.1 deg)'\n"
        "set xlabel 'objects'\nset ylabel 'Mb/s per client'\nset logscale xy\nset grid\n"
        "set key top left\n"
        "plot " << d << " using 1:6 with linespoints lw 2 title 'edgephys (measured)', "
     << d << " using 1:($7>0?$7:1/0) with linespoints pt 6 ps 1.5 title 'paper', "
     << d << " using 1:($8>0?$8:1/0) with lines dt 2 title 'paper / 5 (target)'\n";
  std::ostringstream er;
  er << "set title 'MultiObject: receiver position error'\n"
        "set xlabel 'objects'\nset ylabel 'mm'\nset logscale x\nset grid\nset key top left\n"
        "plot " << d << " using 1:9 with linespoints title 'max vs relay state, same moment', "
     << d << " using 1:10 with linespoints title 'p99 vs relay state, same moment', "
     << d << " using 1:11 with linespoints title 'max vs the relay state sent'\n";
  return {dat.str(),
          {{.stem = prefix + "_steptime", .body = st.str()},
           {.stem = prefix + "_egress", .body = eg.str()},
           {.stem = prefix + "_error", .body = er.str()}}};
}

class MultiObjectScenario final
    : public MeasuringScenario<MultiObjectOptions, std::vector<MultiObjectResult>> {
 public:
  MultiObjectScenario()
      : MeasuringScenario("multiobject",
                          "PhyS MultiObject: step time vs raw Bullet, egress vs the paper",
                          {Json, FillTable, Charts}, "multiobject") {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--objects", objects_, "Box counts (comma separated)");
    AddSceneRelayRunOptions(cmd, &o_.duration_s, &o_.receivers, &o_.relay_settle_steps, "size");
    cmd.add_option("--settle-max", o_.relay_settle_max_s, "Relay run: wall cap on settling (s)");
    cmd.add_option("--relay-max-substeps", o_.relay_max_substeps,
                   "Relay run: PhysicsConfig::max_substeps (steps per relay update)");
    AddStandaloneStepOptions(cmd, &o_.bench_warmup_steps, &o_.bench_steps);
    cmd.add_option("--bench-max", o_.bench_max_s, "Standalone: wall cap on measuring (s)");
    cmd.add_option("--bench-min-steps", o_.bench_min_steps, "Standalone: measured steps at least");
    cmd.add_option("--moving-speed", o_.moving_speed_mps, "Moving: speed above (m/s)");
    cmd.add_option("--seed", o_.seed, "Scene seed");
    cmd.add_option("--stirrer-speed", o_.stirrer_angular_speed, "Stirrer angular speed (rad/s)");
    cmd.add_option("--stirrer-reach", o_.stirrer_reach,
                   "Stirrer paddle half length / container half width (0.95: stirs everything)");
    cmd.add_option("--layers", o_.layers, "Container floor sized for this many layers of boxes");
    cmd.add_option("--stirrer-y", o_.stirrer_center_y, "Stirrer paddle centre height (m)");
    cmd.add_option("--stirrer-half-height", o_.stirrer_half_height,
                   "Stirrer paddle half height (m; 0.4 at y 0.4 spans the ~0.6 m pile)");
    cmd.add_option("--sleep-threshold", o_.sleep_threshold,
                   "PhyS sleeping thresholds (m/s, rad/s); the raw Bullet run keeps Bullet's 0.8 / 1.0");
    cmd.add_option("--rest-freeze", o_.rest_freeze,
                   "PhyS freezes resting bodies (PhysicsConfig::rest_freeze; false: off)");
    AddQuantisationOptions(cmd, &o_.position_step_m, &o_.rotation_bound_deg);
    cmd.add_option("--position-threshold", o_.position_threshold_m,
                   "Send when the client's copy is off by more than this (m; <0: relay default 0.001)");
    cmd.add_option("--rotation-threshold", o_.rotation_threshold_deg,
                   "Send when the client's copy is off by more than this (deg; <0: relay default 0.1)");
    cmd.add_flag("--shared-encoding,!--no-shared-encoding", o_.shared_encoding,
                 "Relay sends state format 9 (the default); --no-shared-encoding: format 2");
    cmd.add_option("--playout-min-delay", o_.playout_min_delay_s,
                   "The display probe's fixed playout delay (s; <0: the SDK's adaptive delay)");
    cmd.add_option("--display-playout-limit", o_.playout_limit_s,
                   "The display probe's third yardstick: the room's playout held to this delay (s; "
                   "edgephys_client_set_max_playout_delay); 0: the adaptive delay alone")
        ->check(CLI::Range(0.0, 4.0));
    cmd.add_option("--ambient-hz", o_.ambient_hz,
                   "Relay's send rate for boxes nobody touches (ReplicationConfig::ambient_hz; 0: default)");
    cmd.add_flag("!--no-bench", o_.bench, "Skip the standalone PhyS vs raw Bullet steps");
    cmd.add_flag("!--no-relay", o_.relay, "Skip the relay run");
    AddExternalRelayOptions(cmd, &o_.external);
  }

  std::string Validate() override {
    if (!ParseList(objects_, &o_.objects)) return "--objects: expected a comma-separated list of counts";
    for (uint32_t n : o_.objects) {
      if (n == 0 || n > 60000) return "--objects: counts must be in 1..60000";
    }
    if (o_.duration_s <= 0 || o_.receivers == 0 || o_.bench_steps <= 0 || o_.bench_warmup_steps < 0 ||
        o_.relay_settle_steps < 0 || o_.relay_max_substeps < 1) {
      return "invalid --duration, --receivers, --bench-steps, --bench-warmup, --settle-steps "
             "or --relay-max-substeps";
    }
    if (std::string e = ValidateExternalRelay(o_.external); !e.empty()) return e;
    if (o_.external.enabled() && !o_.relay) return "--relay needs the relay run (drop --no-relay)";
    return "";
  }

  std::optional<std::vector<MultiObjectResult>> Measure() override { return RunMultiObject(o_); }

  bool Succeeded(const std::vector<MultiObjectResult>& results) const override {
    return !o_.relay || AllRelayRunsOk(results);
  }

 private:
  std::string objects_ = "500,1000,2000,5000,10000";
};

}  // namespace

std::unique_ptr<Scenario> MakeMultiObjectScenario() {
  return std::make_unique<MultiObjectScenario>();
}

}  // namespace edgephys::loadgen
