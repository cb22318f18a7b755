// ccu as a Scenario: options, validation and the report (JSON, table, charts).
#include <CLI/CLI.hpp>
#include <sstream>

#include "loadgen/ccu.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// The JSON of a sample: one field per member, named as the member (nlohmann::json sorts keys).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CcuSample, t, users, egress_bytes_per_s, ingress_bytes_per_s,
                                   updates_per_s, resends_per_s, relay_cpu, physics_step_ms)
// The options a report echoes, named as the members (impaired and measure_every added where
// they apply).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CcuOptions, rooms, ramp_s, duration_s, relay_threads,
                                   shared_encoding, tick_rate_hz, publish_hz)

namespace {

nlohmann::json Summary(const CcuResult& r) {
  return {{"users", r.users},
          {"rooms", r.rooms},
          {"connected", r.connected},
          {"reliable_expected", r.reliable_expected},
          {"reliable_lost", r.reliable_lost},
          {"reliable_duplicated", r.reliable_duplicated},
          {"latency_user_to_user_ms_p50", r.latency_ms_p50},
          {"latency_user_to_user_ms_p99", r.latency_ms_p99},
          {"grab_latency_ms_p50", r.grab_latency_ms_p50},
          {"grab_latency_ms_p99", r.grab_latency_ms_p99},
          {"latency_arrival_ms_p50", r.arrival_latency_ms_p50},
          {"latency_arrival_ms_p99", r.arrival_latency_ms_p99},
          {"grab_latency_arrival_ms_p50", r.grab_arrival_latency_ms_p50},
          {"grab_latency_arrival_ms_p99", r.grab_arrival_latency_ms_p99},
          {"arrival_time_fallbacks", r.arrival_time_fallbacks},
          {"latency_relay_wait_ms_mean", r.relay_wait_ms_mean},
          {"latency_physics_step_ms_p99", r.physics_step_ms_p99},
          {"bot_pass_ms_p50", r.bot_pass_ms_p50},
          {"bot_pass_ms_p99", r.bot_pass_ms_p99},
          {"latency_interpolation_ms", r.interpolation_delay_ms},
          {"relay_cpu_mean", r.relay_cpu_mean},
          {"egress_bytes_per_s_per_user", r.egress_bytes_per_s_per_user},
          {"relay_us_per_update", r.relay_us_per_update},
          {"bytes_per_update", r.bytes_per_update},
          {"hand_update_ratio", r.expected_update_ratio},
          {"hand_updates_measured", r.hand_updates_measured},
          {"hand_unmatched", r.hand_unmatched},
          {"cross_room_samples", r.cross_room_samples},
          {"impaired_users", r.impaired_users},
          {"impaired_dropped_up", r.impaired_dropped_up},
          {"impaired_dropped_down", r.impaired_dropped_down}};
}

// External relay: the server-side figures' provenance, and what it cannot give.
void AddExternalNotes(const CcuOptions& o, const CcuResult& r, nlohmann::json* summary) {
  if (!o.external.enabled()) return;
  (*summary)["metrics_failures"] = r.metrics_failures;
  if (!r.metrics_error.empty()) (*summary)["metrics_error"] = r.metrics_error;
  (*summary)["notes"] = {
      {"egress_bytes_per_s_per_user",
       "edgephys_bytes_sent_total differences over the relay's whole process (all rooms)"},
      {"relay_cpu_mean", ExternalRelayCpuNote(o.external)},
      {"latency_physics_step_ms_p99",
       "edgephys_physics_step_seconds_sum / edgephys_physics_steps_total per second"},
      {"latency_relay_wait_ms_mean",
       "half a tick at --tick-rate: the external relay's own tick rate is not exported"}};
}

nlohmann::json Series(const CcuResult& r) {
  nlohmann::json a = nlohmann::json::array();
  for (const CcuSample& s : r.series) a.push_back(s);
  return a;
}

// One run: "summary" and "series" at the top level too (what single-count tools read).
nlohmann::json Json(const CcuOptions& o, const std::vector<CcuResult>& results) {
  nlohmann::json j = {{"options", o}};
  if (results.size() == 1) {
    j["summary"] = Summary(results[0]);
    AddExternalNotes(o, results[0], &j["summary"]);
    j["series"] = Series(results[0]);
  }
  j["runs"] = nlohmann::json::array();
  for (const CcuResult& r : results) {
    nlohmann::json summary = Summary(r);
    AddExternalNotes(o, r, &summary);
    j["runs"].push_back({{"summary", summary}, {"series", Series(r)}});
  }
  if (o.impaired_fraction > 0) {
    j["options"]["impaired"] = {{"fraction", o.impaired_fraction}, {"loss", o.impaired_loss},
                                {"delay_ms", o.impaired_delay_ms}};
  }
  if (o.external.enabled()) {
    j["relay"] = ExternalRelayJson(o.external);
    j["options"]["measure_every"] = o.measure_every;
  } else if (o.measure_every != 1) {
    j["options"]["measure_every"] = o.measure_every;
  }
  return j;
}

void FillTable(const CcuOptions& o, const std::vector<CcuResult>& results, Table* t) {
  t->Line("%6s %5s %9s %8s %8s %8s %8s %8s %8s %8s %8s %8s %8s %8s %9s %8s %9s %8s %8s\n", "users",
          "rooms", "connected", "lost", "lat p50", "lat p99", "arr p50", "arr p99", "grab p50",
          "grab p99", "garr p50", "garr p99", "step p99", "cpu", "B/s/user", "upd ratio",
          "unmatched", "us/upd", "B/upd");
  for (const CcuResult& r : results) {
    t->Line("%6u %5u %9u %8llu %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %8.1f %8.2f %8.2f "
            "%9.0f %8.2f %9.4f %8.3f %8.2f\n",
            r.users, r.rooms, r.connected, static_cast<unsigned long long>(r.reliable_lost),
            r.latency_ms_p50, r.latency_ms_p99, r.arrival_latency_ms_p50, r.arrival_latency_ms_p99,
            r.grab_latency_ms_p50, r.grab_latency_ms_p99, r.grab_arrival_latency_ms_p50,
            r.grab_arrival_latency_ms_p99, r.physics_step_ms_p99, r.relay_cpu_mean,
            r.egress_bytes_per_s_per_user, r.expected_update_ratio,
            r.hand_updates_measured
                ? static_cast<double>(r.hand_unmatched) / static_cast<double>(r.hand_updates_measured)
                : 0.0,
            r.relay_us_per_update, r.bytes_per_update);
  }
  t->Text("(latencies in ms, user to user on loopback: lat/grab until the receiving bot's SDK "
          "read it, arr/garr until it reached that bot's socket (kernel timestamp); cpu = relay "
          "thread CPU / wall; unmatched = measured hand poses matched to no publish, not in the "
          "percentiles; us/upd and B/upd = relay CPU microseconds and sealed UDP payload bytes "
          "per entity update delivered)\n");
  if (o.impaired_fraction > 0) {
    for (const CcuResult& r : results) {
      t->Line("(%u bots on a %.0f %% loss, %.0f ms link: %llu datagrams dropped to the relay, %llu "
              "from it)\n",
              r.impaired_users, o.impaired_loss * 100, o.impaired_delay_ms,
              static_cast<unsigned long long>(r.impaired_dropped_up),
              static_cast<unsigned long long>(r.impaired_dropped_down));
    }
  }
  if (o.external.enabled()) {
    t->Line("(external relay %s: egress, updates and step time from its /metrics, process-wide; "
            "cpu = its process CPU from /proc%s)\n",
            o.external.relay.c_str(), o.external.relay_pid > 0 ? "" : ": unknown without --relay-pid");
  }
}

// <prefix>.dat (one index block per run) and the chart <prefix>.png / .svg: users, egress and
// relay CPU over time.
ChartSet Charts(const CcuOptions&, const std::vector<CcuResult>& results, const std::string& prefix) {
  std::ostringstream dat;
  for (const CcuResult& r : results) {
    dat << "# users " << r.users << "\n# t users egress_KBps ingress_KBps updates_per_s cpu step_ms\n";
    for (const CcuSample& s : r.series) {
      dat << s.t << " " << s.users << " " << s.egress_bytes_per_s / 1000 << " "
          << s.ingress_bytes_per_s / 1000 << " " << s.updates_per_s << " " << s.relay_cpu << " "
          << s.physics_step_ms << "\n";
    }
    dat << "\n\n";
  }
  std::ostringstream gp;
  gp << "set title 'ccu: relay load over time'\n"
     << "set xlabel 'time (s)'\nset ylabel 'users, KB/s'\nset y2label 'relay CPU (cores)'\n"
     << "set y2tics\nset grid\nset key top left\nplot ";
  for (size_t i = 0; i < results.size(); ++i) {
    gp << "'" << prefix << ".dat' index " << i << " using 1:2 with lines title 'users ("
       << results[i].users << ")', '' index " << i << " using 1:3 with lines title 'egress KB/s', '' index "
       << i << " using 1:6 axes x1y2 with lines title 'relay cpu'"
       << (i + 1 < results.size() ? ", " : "\n");
  }
  return {dat.str(), {{.stem = prefix, .body = gp.str()}}};
}

class CcuScenario final : public MeasuringScenario<CcuOptions, std::vector<CcuResult>> {
 public:
  CcuScenario()
      : MeasuringScenario("ccu", "Concurrent users: bots with hands and grabbed objects",
                          {Json, FillTable, Charts}, "ccu") {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--users", users_, "User counts (comma separated; one run each)");
    cmd.add_option("--rooms", o_.rooms, "Rooms the users spread over");
    cmd.add_option("--ramp", o_.ramp_s, "Seconds over which users join");
    cmd.add_option("--duration", o_.duration_s, "Measured seconds after the ramp");
    AddRelayRoomOptions(cmd, &o_.tick_rate_hz, &o_.packet_auth);
    cmd.add_option("--relay-threads", o_.relay_threads,
                   "Relay threads for ticks and PhyS (1: the relay keeps to one core; the bots use "
                   "the other)");
    cmd.add_flag("--shared-encoding,!--no-shared-encoding", o_.shared_encoding,
                 "In-process relay: rooms use the shared-delta state format 9 (the relay's "
                 "default); --no-shared-encoding: format 2");
    cmd.add_option("--measure-every", o_.measure_every,
                   "Only every K-th bot matches poses for latency (all still decode; 1: all)")
        ->check(CLI::Range(1u, 1000000u));
    cmd.add_option("--impaired", o_.impaired_fraction,
                   "Fraction of the bots on a lossy, delayed link of their own (both directions; "
                   "0: none)")
        ->check(CLI::Range(0.0, 1.0));
    cmd.add_option("--impaired-loss", o_.impaired_loss, "Loss of the --impaired bots' links (per direction)")
        ->check(CLI::Range(0.0, 1.0));
    cmd.add_option("--impaired-delay-ms", o_.impaired_delay_ms,
                   "One-way delay of the --impaired bots' links (ms)")
        ->check(CLI::Range(0.0, 10000.0));
    cmd.add_option("--samples", o_.samples_path,
                   "Write every latency sample (and unmatched hand pose) to this CSV (with several "
                   "--users: one file per count, suffixed .<users>)");
    AddExternalRelayOptions(cmd, &o_.external);
  }

  std::string Validate() override {
    if (!ParseList(users_, &o_.users) || o_.rooms == 0 || o_.duration_s <= 0) {
      return "--users must be a list of counts; --rooms and --duration positive";
    }
    if (o_.measure_every == 0) return "--measure-every must be positive";
    return ValidateExternalRelay(o_.external);
  }

  std::optional<std::vector<CcuResult>> Measure() override { return RunCcu(o_); }

 private:
  std::string users_ = "100";
};

}  // namespace

std::unique_ptr<Scenario> MakeCcuScenario() { return std::make_unique<CcuScenario>(); }

}  // namespace edgephys::loadgen
