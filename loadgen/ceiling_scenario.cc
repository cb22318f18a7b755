// ceiling as a Scenario: options, validation and the report (JSON, table; no charts).
#include <CLI/CLI.hpp>
#include <thread>

#include "loadgen/ceiling.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// The JSON of a relay run and of an iperf3 run: one field per member, named as the member
// (nlohmann::json sorts keys).
// The options a report echoes, named as the members (with the machine's thread count added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CeilingOptions, io_threads, clients, rooms, entities_per_client,
                                   publish_hz, tick_rate_hz, warmup_s, duration_s, iperf_seconds,
                                   iperf_length, repeat)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CeilingRelayRun, io_threads, clients_joined, seconds,
                                   packets_per_s, bytes_per_s, rx_packets_per_s, tx_packets_per_s,
                                   mean_datagram_bytes, relay_cpu_cores, bots_cpu_cores, drops,
                                   rejected)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(CeilingIperf, ran, error, length, seconds, sent_packets_per_s,
                                   packets_per_s, bytes_per_s, lost_percent)

namespace {

// Every repetition and the medians over them.
struct CeilingResults {
  std::vector<CeilingRepetition> reps;
  std::vector<CeilingSummary> summary;
};

nlohmann::json Json(const CeilingOptions& o, const CeilingResults& results) {
  const auto& [reps, summary] = results;
  nlohmann::json j = {{"options", o}};
  j["options"]["hardware_concurrency"] = std::thread::hardware_concurrency();
  j["summary"] = nlohmann::json::array();
  for (const CeilingSummary& s : summary) {
    j["summary"].push_back({{"io_threads", s.io_threads},
                            {"clients_joined", s.clients_joined},
                            {"relay_packets_per_s", s.packets_per_s},
                            {"relay_bytes_per_s", s.bytes_per_s},
                            {"mean_datagram_bytes", s.mean_datagram_bytes},
                            {"iperf3_packets_per_s", s.iperf_packets_per_s},
                            {"iperf3_bytes_per_s", s.iperf_bytes_per_s},
                            {"ratio_packets", s.ratio_packets},
                            {"ratio_bytes", s.ratio_bytes},
                            {"relay_cpu_cores", s.relay_cpu_cores},
                            {"bots_cpu_cores", s.bots_cpu_cores},
                            {"drops", s.drops}});
  }
  j["repetitions"] = nlohmann::json::array();
  for (const CeilingRepetition& r : reps) {
    j["repetitions"].push_back({{"relay", r.relay}, {"iperf3", r.iperf}});
  }
  if (o.external.enabled()) {
    j["relay"] = ExternalRelayJson(o.external);
    j["notes"] = {
        {"io_threads, tick_rate_hz",
         "the external relay's own flags (--io-threads, --tick-rate); echoed, not set"},
        {"relay_packets_per_s, relay_bytes_per_s, drops",
         "differences of edgephys_packets_received_total + edgephys_packets_sent_total, "
         "edgephys_bytes_*_total, edgephys_io_queue_drops_total + edgephys_send_errors_total "
         "over the window (process-wide); 0 if a /metrics scrape failed"},
        {"replication",
         "in-process the relay sends every moving entity each tick (fixed_rate_hz = tick rate); "
         "an external relay uses its own replication flags, so its egress may be lower"},
        {"relay_cpu_cores", ExternalRelayCpuNote(o.external)}};
  }
  return j;
}

// Medians per --io-threads value; why iperf3 did not run, if it did not.
void FillTable(const CeilingOptions&, const CeilingResults& results, Table* t) {
  const auto& [reps, summary] = results;
  t->Line("%-12s %8s %12s %12s %10s %13s %13s %9s %9s %9s %9s %6s\n", "relay", "clients", "pkt/s",
          "MB/s", "B/datagram", "iperf3 pkt/s", "iperf3 MB/s", "ratio pkt", "ratio B",
          "relay CPU", "bots CPU", "drops");
  for (const CeilingSummary& s : summary) {
    const std::string name = "io-threads " + std::to_string(s.io_threads);
    t->Line("%-12s %8u %12.0f %12.2f %10.0f %13.0f %13.2f %9.3f %9.3f %9.2f %9.2f %6llu\n",
            name.c_str(), s.clients_joined, s.packets_per_s, s.bytes_per_s / 1e6,
            s.mean_datagram_bytes, s.iperf_packets_per_s, s.iperf_bytes_per_s / 1e6,
            s.ratio_packets, s.ratio_bytes, s.relay_cpu_cores, s.bots_cpu_cores,
            static_cast<unsigned long long>(s.drops));
  }
  t->Line("(medians of %zu repetition%s; pkt/s and MB/s = relay ingress + egress; iperf3 = "
          "datagrams delivered to its server)\n",
          reps.size(), reps.size() == 1 ? "" : "s");
  for (const CeilingRepetition& r : reps) {
    if (!r.iperf.ran) {
      t->Text("iperf3: " + r.iperf.error + "\n");
      break;
    }
  }
}

class CeilingScenario final : public MeasuringScenario<CeilingOptions, CeilingResults> {
 public:
  CeilingScenario()
      : MeasuringScenario("ceiling", "Relay packets/s and bytes/s vs the iperf3 -u loopback ceiling",
                          {Json, FillTable}) {
    SetProgressFlag(&o_.progress, "Hide progress lines");
  }

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--io-threads", threads_,
                   "Relay --io-threads values (comma separated; one run each)");
    cmd.add_option("--clients", o_.clients, "Bot clients");
    cmd.add_option("--rooms", o_.rooms, "Rooms the clients spread over");
    cmd.add_option("--entities", o_.entities_per_client, "Entities each client moves");
    cmd.add_option("--publish-hz", o_.publish_hz, "Client publish rate");
    AddRelayRoomOptions(cmd, &o_.tick_rate_hz, &o_.packet_auth);
    AddWindowOptions(cmd, &o_.warmup_s, &o_.duration_s, " per relay run");
    cmd.add_option("--iperf-seconds", o_.iperf_seconds, "iperf3 -t");
    cmd.add_option("--iperf-length", o_.iperf_length,
                   "iperf3 -l (bytes; 0: the relay's mean datagram size)");
    cmd.add_option("--iperf-port", o_.iperf_port, "iperf3 port (0: a free one)");
    cmd.add_option("--repeat", o_.repeat, "Repetitions (medians reported)");
    AddExternalRelayOptions(cmd, &o_.external);
  }

  std::string Validate() override {
    if (!ParseList(threads_, &o_.io_threads) || o_.clients == 0 || o_.rooms == 0 ||
        o_.entities_per_client == 0 || o_.publish_hz <= 0 || o_.tick_rate_hz <= 0 ||
        o_.tick_rate_hz > 1000 || o_.warmup_s < 0 || o_.duration_s <= 0 || o_.duration_s > 120 ||
        o_.iperf_seconds <= 0 || o_.iperf_seconds > 120 || o_.repeat == 0 || o_.repeat > 20) {
      return "invalid ceiling options (durations 0..120 s, repeat 1..20, counts > 0)";
    }
    for (size_t t : o_.io_threads) {
      if (t == 0 || t > 64) return "--io-threads: values must be in 1..64";
    }
    if (o_.external.enabled() && o_.io_threads.size() != 1) {
      return "--relay: one --io-threads value, the external relay's own";
    }
    return ValidateExternalRelay(o_.external);
  }

  std::optional<CeilingResults> Measure() override {
    CeilingResults results;
    results.reps = RunCeiling(o_);
    results.summary = SummarizeCeiling(o_, results.reps);
    return results;
  }

 private:
  std::string threads_ = "1,2";
};

}  // namespace

std::unique_ptr<Scenario> MakeCeilingScenario() { return std::make_unique<CeilingScenario>(); }

}  // namespace edgephys::loadgen
