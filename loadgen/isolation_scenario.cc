// isolation as a Scenario: options, validation and the report (JSON, table, chart).
#include <CLI/CLI.hpp>
#include <cmath>
#include <sstream>

#include "loadgen/isolation.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// The options a report echoes, named as the members (with b_mode and b_decode added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(IsolationOptions, users, boxes, b_receivers, ramp_s, phase_s,
                                   after_phase, late_join_delay_s, late_join_timeout_s, publish_hz,
                                   measure_every, seed, burn_nice, b_thread_nice, b_thread_idle)
// NaN becomes JSON null (nlohmann::json writes non-finite numbers as null).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(IsolationPhase, name, start_s, end_s, samples, latency_ms_p50,
                                   latency_ms_p99, arrival_latency_ms_p50, arrival_latency_ms_p99,
                                   delivered_fraction, bot_pass_ms_p99, relay_figures,
                                   egress_bytes_per_s, ingress_bytes_per_s, relay_cpu,
                                   physics_step_ms_mean, physics_steps_per_s)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(IsolationBin, t, samples, latency_ms_p50, latency_ms_p99,
                                   arrival_latency_ms_p50, arrival_latency_ms_p99)

namespace {

nlohmann::json Json(const IsolationOptions& o, const IsolationResult& r) {
  nlohmann::json j = {{"options", o}};
  j["options"].update({{"b_mode", o.b_burn ? "burn" : "scene"},
                       {"b_decode", o.b_decode ? "all" : "joiner"}});
  if (o.external.enabled()) {
    j["relay"] = ExternalRelayJson(o.external);
    j["notes"] = {
        {"relay figures",
         "differences of the external relay's /metrics counters over each phase "
         "(edgephys_bytes_sent_total, edgephys_bytes_received_total, edgephys_physics_steps_total, "
         "edgephys_physics_step_seconds_sum/_count): process-wide, all rooms"},
        {"relay_cpu", ExternalRelayCpuNote(o.external)},
        {"tick_rate_hz, physics_threads", "the external relay's own flags; not exported"}};
  } else {
    j["options"]["tick_rate_hz"] = o.tick_rate_hz;
    j["options"]["physics_threads"] = o.physics_threads;
    j["options"]["physics_nice"] = o.physics_nice;
    j["options"]["physics_idle"] = o.physics_idle;
    j["relay"] = {{"external", false}, {"cpu_source", "relay thread"}};
  }
  j["summary"] = {{"users", r.users},
                  {"connected", r.connected},
                  {"boxes", r.boxes},
                  {"b_ok", r.b_ok},
                  {"b_spawn_send_s", r.b_spawn_send_s},
                  {"scene_entities", r.scene_entities},
                  {"late_join_ok", r.late_join_ok},
                  {"late_join_s", r.late_join_s},
                  {"late_join_spawns", r.late_join_spawns},
                  {"p99_ratio_with_b_to_alone", r.p99_ratio},
                  {"arrival_p99_ratio_with_b_to_alone", r.arrival_p99_ratio},
                  {"metrics_failures", r.metrics_failures}};
  if (o.b_burn) {
    j["summary"]["burn_steps"] = r.burn_steps;
    j["summary"]["burn_step_ms_mean"] = r.burn_step_ms_mean;
  }
  if (!r.b_error.empty()) j["summary"]["b_error"] = r.b_error;
  if (!r.b_thread_policy.empty()) j["summary"]["b_thread_policy"] = r.b_thread_policy;
  if (!r.metrics_error.empty()) j["summary"]["metrics_error"] = r.metrics_error;
  j["phases"] = r.phases;
  j["series"] = r.bins;
  return j;
}

void FillTable(const IsolationOptions& o, const IsolationResult& r, Table* t) {
  t->Line("room A: %u users (%u joined); room B: %u boxes%s\n", r.users, r.connected, r.boxes,
          o.external.enabled() ? " (external relay)" : "");
  t->Line("%-7s %6s %8s %8s %8s %8s %8s %8s %10s %6s %9s\n", "phase", "secs", "samples", "lat p50",
          "lat p99", "arr p50", "arr p99", "delivered", "egress KB/s", "cpu", "step ms");
  for (const IsolationPhase& p : r.phases) {
    t->Line("%-7s %6.1f %8llu %8.1f %8.1f %8.1f %8.1f %8.3f %10.0f %6.2f %9.2f\n", p.name.c_str(),
            p.end_s - p.start_s, static_cast<unsigned long long>(p.samples), p.latency_ms_p50,
            p.latency_ms_p99, p.arrival_latency_ms_p50, p.arrival_latency_ms_p99,
            p.delivered_fraction, p.egress_bytes_per_s / 1000, p.relay_cpu, p.physics_step_ms_mean);
  }
  t->Line("A p99 with B / alone: %.2f (SDK), %.2f (socket)\n", r.p99_ratio, r.arrival_p99_ratio);
  if (o.b_burn) {
    t->Line("with_b: no room B; physics-burn (%u boxes, niceness %d) in its own process: %llu steps, "
            "mean %.2f ms%s%s\n", r.boxes, o.burn_nice, static_cast<unsigned long long>(r.burn_steps),
            r.burn_step_ms_mean, r.b_error.empty() ? "" : "; ", r.b_error.c_str());
  } else if (r.late_join_ok) {
    t->Line("late joiner: every one of B's %u entities %.3f s after its join request\n", r.scene_entities, r.late_join_s);
  } else {
    t->Line("late joiner: %u of %u entities received (incomplete)%s%s\n", r.late_join_spawns,
            r.scene_entities, r.b_error.empty() ? "" : "; ", r.b_error.c_str());
  }
  t->Text("(latencies in ms, A's right hands user to user: lat until the receiving bot's SDK read "
          "it, arr until it reached that bot's socket; cpu = relay CPU cores, nan = unknown)\n");
}

// <prefix>.dat: A's latency per bin; the chart <prefix>.png / .svg with the phases marked.
ChartSet Charts(const IsolationOptions&, const IsolationResult& r, const std::string& prefix) {
  std::ostringstream dat;
  dat << "# t samples lat_p50 lat_p99 arr_p50 arr_p99\n";
  for (const IsolationBin& b : r.bins) {
    dat << b.t << " " << b.samples << " " << b.latency_ms_p50 << " " << b.latency_ms_p99 << " "
        << b.arrival_latency_ms_p50 << " " << b.arrival_latency_ms_p99 << "\n";
  }
  std::ostringstream gp;
  gp << "set title 'isolation: room A hand latency, room B (" << r.boxes << " boxes) joins and leaves'\n"
     << "set xlabel 'time (s)'\nset ylabel 'latency (ms)'\nset grid\nset key bottom right\n";
  int n = 0;
  for (const IsolationPhase& p : r.phases) {
    ++n;  // arrow and label of phase n share its number
    gp << "set arrow " << n << " from " << p.start_s << ", graph 0 to " << p.start_s
       << ", graph 1 nohead dashtype 2\n"
       << "set label " << n << " '" << p.name << "' at " << p.start_s
       << ", graph 0.95 offset 0.5,0 noenhanced\n";
  }
  gp << "plot '" << prefix << ".dat' using 1:3 with lines title 'SDK p50', '' using 1:4 with lines "
     << "title 'SDK p99', '' using 1:5 with lines title 'socket p50', '' using 1:6 with lines "
     << "title 'socket p99'\n";
  return {dat.str(), {{.stem = prefix, .body = gp.str()}}};
}

class IsolationScenario final : public MeasuringScenario<IsolationOptions, IsolationResult> {
 public:
  IsolationScenario()
      : MeasuringScenario("isolation",
                          "Room A's hand latency alone, beside a heavy PhyS room B, and after B leaves",
                          {Json, FillTable, Charts}, "isolation") {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--users", o_.users, "Room A's users (ccu-style bots)");
    cmd.add_option("--boxes", o_.boxes, "Room B's boxes (the multiobject scene)");
    cmd.add_option("--b-receivers", o_.b_receivers, "Room B's receivers besides the host");
    cmd.add_option("--ramp", o_.ramp_s, "Seconds over which A's users join");
    cmd.add_option("--phase", o_.phase_s, "Seconds of each phase (alone, with B, after)");
    cmd.add_flag("!--no-after", o_.after_phase, "No third phase after B leaves");
    cmd.add_option("--late-join-delay", o_.late_join_delay_s,
                   "Seconds after B's spawns are sent before the late joiner joins B");
    cmd.add_option("--late-join-timeout", o_.late_join_timeout_s,
                   "Seconds the late joiner waits for B's scene, at most");
    cmd.add_option("--publish-hz", o_.publish_hz, "A's pose updates per second");
    cmd.add_option("--tick-rate", o_.tick_rate_hz, "In-process relay: room tick rate");
    cmd.add_option("--physics-threads", o_.physics_threads,
                   "In-process relay: threads for ticks and PhyS (RelayConfig::physics_threads)");
    cmd.add_option("--physics-nice", o_.physics_nice,
                   "In-process relay: niceness of the physics threads (RelayConfig::physics_nice, "
                   "0..19; -1: the relay's default)")
        ->check(CLI::Range(-1, 19));
    cmd.add_flag("--physics-idle", o_.physics_idle,
                 "In-process relay: physics threads under SCHED_IDLE (RelayConfig::physics_idle)");
    cmd.add_option("--bin", o_.bin_s, "Seconds per bin of the latency series");
    cmd.add_option("--measure-every", o_.measure_every,
                   "Only every K-th A bot matches poses for latency (all still decode; 1: all)");
    cmd.add_option("--seed", o_.seed, "Scene seed");
    cmd.add_option("--b-mode", b_mode_,
                   "scene: room B on the relay; burn (a control): no room B, the same scene stepped "
                   "back to back by a separate physics-burn process during with_b")
        ->check(CLI::IsMember({"scene", "burn"}));
    cmd.add_option("--burn-nice", o_.burn_nice, "--b-mode burn: the burner's niceness")
        ->check(CLI::Range(0, 19));
    cmd.add_option("--b-decode", b_decode_,
                   "all: B's host and receivers decode B's states; joiner: they acknowledge without "
                   "decoding (the relay's work is the same), only the late joiner decodes")
        ->check(CLI::IsMember({"all", "joiner"}));
    cmd.add_option("--b-thread-nice", o_.b_thread_nice, "Niceness of the thread running B's clients")
        ->check(CLI::Range(0, 19));
    cmd.add_flag("--b-thread-idle", o_.b_thread_idle,
                 "Run B's clients' thread under SCHED_IDLE (only on cores nothing else wants)");
    AddExternalRelayOptions(cmd, &o_.external);
  }

  std::string Validate() override {
    if (o_.users < 2) return "--users must be at least 2";
    if (o_.boxes == 0 || o_.phase_s <= 0 || o_.publish_hz <= 0 || o_.bin_s <= 0) {
      return "--boxes, --phase, --publish-hz and --bin must be positive";
    }
    if (o_.measure_every == 0) return "--measure-every must be positive";
    o_.b_burn = b_mode_ == "burn";
    o_.b_decode = b_decode_ == "all";
    if (o_.late_join_timeout_s <= 0 || o_.late_join_delay_s < 0) {
      return "--late-join-timeout positive, --late-join-delay not negative";
    }
    return ValidateExternalRelay(o_.external);
  }

  std::optional<IsolationResult> Measure() override { return RunIsolation(o_); }

  bool Succeeded(const IsolationResult& r) const override {
    return r.connected == r.users && r.b_ok;
  }

 private:
  std::string b_mode_ = "scene", b_decode_ = "all";
};

}  // namespace

std::unique_ptr<Scenario> MakeIsolationScenario() { return std::make_unique<IsolationScenario>(); }

}  // namespace edgephys::loadgen
