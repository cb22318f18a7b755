// relay-compare as a Scenario: options, validation and the report (JSON, table, charts).
#include <CLI/CLI.hpp>
#include <sstream>

#include "loadgen/relay_compare.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// The JSON of a result: one field per member, named as the member (nlohmann::json sorts keys).
// The mode is added by name.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(RelayCompareResult, objects, rate_hz,
                                   egress_bytes_per_s_per_receiver,
                                   socket_bytes_per_s_per_receiver, ip_udp_bytes_per_s_per_receiver,
                                   updates_per_s_per_receiver,
                                   bytes_per_update, pos_err_max_m, pos_err_p99_m,
                                   rot_err_max_deg, rot_err_p99_deg, paper_bytes_per_s, samples)
// The options a report echoes, named as the members (with the motion's added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(RelayCompareOptions, rate_hz, duration_s, receivers,
                                   position_step_m, rotation_bound_deg, shared_encoding)

namespace {

// {"scenario":"relay-compare","options":{...},"results":[...]}.
nlohmann::json Json(const RelayCompareOptions& o, const std::vector<RelayCompareResult>& results) {
  nlohmann::json j = {{"options", o}};
  j["options"].update(o.motion);
  j["results"] = nlohmann::json::array();
  for (const auto& r : results) {
    nlohmann::json e = r;
    e["mode"] = std::string(ReplicationModeName(r.mode));
    e["ratio_to_paper"] = RatioOr0(r.egress_bytes_per_s_per_receiver, r.paper_bytes_per_s);
    j["results"].push_back(e);
  }
  if (o.external.enabled()) {
    j["relay"] = ExternalRelayJson(o.external);
    j["notes"] = {
        {"mode, rate_hz, position_step_m, rotation_bound_deg, thresholds",
         "the external relay's own flags (--position-step, ...; its format is edgephys); the load "
         "generator only echoes its options and cannot check them"},
        {"egress_bytes_per_s_per_receiver",
         "edgephys_bytes_sent_total difference over the window (process-wide) minus the bytes "
         "the host's socket received, over receivers; null if /metrics failed"},
        {"pos_err, rot_err", "against the host's published truth, as in-process"}};
  }
  return j;
}

// Beside the paper's columns.
void FillTable(const RelayCompareOptions&, const std::vector<RelayCompareResult>& results,
               Table* t) {
  t->Line("%-9s %7s %11s %11s %9s %9s %7s %9s %7s %9s %9s %9s %9s\n", "mode", "objects",
          "KB/s relay", "KB/s sock", "KB/s IP+UDP", "paper KB/s", "ratio", "upd/s", "B/upd",
          "pos max mm", "pos p99", "rot max", "rot p99");
  for (const auto& r : results) {
    t->Line("%-9s %7u %11.2f %11.2f %9.2f %9.2f %7.3f %9.1f %7.2f %9.3f %9.3f %9.4f %9.4f\n",
            std::string(ReplicationModeName(r.mode)).c_str(), r.objects,
            r.egress_bytes_per_s_per_receiver / 1000, r.socket_bytes_per_s_per_receiver / 1000,
            r.ip_udp_bytes_per_s_per_receiver / 1000, r.paper_bytes_per_s / 1000,
            RatioOr0(r.egress_bytes_per_s_per_receiver, r.paper_bytes_per_s), r.updates_per_s_per_receiver,
            r.bytes_per_update, r.pos_err_max_m * 1000, r.pos_err_p99_m * 1000, r.rot_err_max_deg,
            r.rot_err_p99_deg);
  }
  t->Text("(KB = 1000 bytes; relay and sock: UDP payload as sent, sealed; IP+UDP: the 28 bytes of "
          "headers of every datagram received, beside them; paper KB/s: the paper's relay column "
          "for paper/edgephys, Photon for photon)\n");
}

// <prefix>.dat (one index block per mode present), <prefix>_bandwidth and <prefix>_error.
ChartSet Charts(const RelayCompareOptions&, const std::vector<RelayCompareResult>& results,
                const std::string& prefix) {
  ChartSet set;
  std::ostringstream dat;
  std::vector<std::string> present;
  for (const char* m : {"photon", "paper", "edgephys", "float"}) {
    bool any = false;
    for (const auto& r : results) {
      if (ReplicationModeName(r.mode) != m) continue;
      if (!any) dat << "# mode " << m << "\n# objects kBps_relay kBps_paper pos_max_mm rot_max_deg\n";
      any = true;
      dat << r.objects << " " << r.egress_bytes_per_s_per_receiver / 1000 << " "
          << r.paper_bytes_per_s / 1000 << " " << r.pos_err_max_m * 1000 << " "
          << r.rot_err_max_deg << "\n";
    }
    if (any) {
      dat << "\n\n";
      present.push_back(m);
    }
  }
  set.data = dat.str();
  const std::string d = "'" + prefix + ".dat'";
  // Block i's columns `using` as a plot element titled `title`.
  auto series = [&](size_t i, const char* using_, const std::string& title) {
    return d + " index " + std::to_string(i) + " using " + using_ + " title '" + title + "'";
  };
  std::ostringstream bw;
  bw << "set title 'Relay egress per receiver vs objects (12 sends/s per object)'\n"
        "set xlabel 'objects'\nset ylabel 'KB/s per receiver'\nset logscale xy\nset key top left\n"
        "set grid\nplot ";
  for (size_t i = 0; i < present.size(); ++i) {
    bw << series(i, "1:2 with linespoints", present[i] + " (measured)") << ", ";
  }
  bw << d << " index 0 using 1:3 with points pt 6 ps 1.5 title 'paper: Photon', ";
  bw << d << " index 1 using 1:3 with points pt 8 ps 1.5 title 'paper: relay'\n";
  set.charts.push_back({.stem = prefix + "_bandwidth", .body = bw.str()});
  std::ostringstream err;
  err << "set title 'Bandwidth vs accuracy (max error of the last received state)'\n"
         "set xlabel 'KB/s per receiver'\nset ylabel 'max position error (mm)'\nset logscale x\n"
         "set y2label 'max rotation error (deg)'\nset y2tics\nset grid\nset key top right\nplot ";
  for (size_t i = 0; i < present.size(); ++i) {
    err << series(i, "2:4 with linespoints", present[i] + " position") << ", "
        << series(i, "2:5 axes x1y2 with points", present[i] + " rotation")
        << (i + 1 < present.size() ? ", " : "\n");
  }
  set.charts.push_back({.stem = prefix + "_error", .body = err.str()});
  return set;
}

class RelayCompareScenario final
    : public MeasuringScenario<RelayCompareOptions, std::vector<RelayCompareResult>> {
 public:
  RelayCompareScenario()
      : MeasuringScenario("relay-compare", "The paper's relay bandwidth experiment",
                          {Json, FillTable, Charts}, "relay_compare") {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--objects", objects_, "Object counts (comma separated)");
    cmd.add_option("--modes", modes_, "Modes: photon,paper,edgephys,float");
    cmd.add_option("--rate", o_.rate_hz, "Sends per second per object");
    AddWindowOptions(cmd, &o_.warmup_s, &o_.duration_s, " per mode and size");
    cmd.add_option("--receivers", o_.receivers, "Receiving clients");
    AddMotionOptions(cmd, &o_.motion, "Motion seed");
    AddQuantisationOptions(cmd, &o_.position_step_m, &o_.rotation_bound_deg);
    cmd.add_option("--position-threshold", o_.position_threshold_m, "Selective sync threshold (m)");
    cmd.add_flag("--shared-encoding,!--no-shared-encoding", o_.shared_encoding,
                 "edgephys mode: state format 9 (the relay's default); --no-shared-encoding: 2");
    cmd.add_option("--rotation-threshold", o_.rotation_threshold_deg,
                   "Selective sync threshold (deg)");
    AddExternalRelayOptions(cmd, &o_.external);
  }

  std::string Validate() override {
    if (!ParseList(objects_, &o_.objects)) return "--objects: expected a comma-separated list of counts";
    std::string unknown;
    if (!ParseNames(modes_, ParseReplicationMode, &o_.modes, &unknown)) {
      return "--modes: unknown mode '" + unknown + "'";
    }
    if (o_.rate_hz <= 0 || o_.duration_s <= 0 || o_.receivers == 0) {
      return "--rate, --duration and --receivers must be positive";
    }
    if (o_.external.enabled() &&
        (o_.modes.size() != 1 || o_.modes[0] != ReplicationMode::kEdgephys)) {
      return "--relay: --modes edgephys only (the emulations are plug-ins of the in-process relay)";
    }
    return ValidateExternalRelay(o_.external);
  }

  std::optional<std::vector<RelayCompareResult>> Measure() override {
    return RunRelayCompare(o_);
  }

 private:
  std::string objects_ = "32,64,128,256,512", modes_ = "photon,paper,edgephys";
};

}  // namespace

std::unique_ptr<Scenario> MakeRelayCompareScenario() {
  return std::make_unique<RelayCompareScenario>();
}

}  // namespace edgephys::loadgen
