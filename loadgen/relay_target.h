// RelayTarget: the relay a scenario's bots talk to — either one the scenario starts in-process
// (on its own thread, as edgephys-relay runs it) or an EXTERNAL edgephys-relay process given by
// --relay HOST:PORT --secret S [--metrics HOST:PORT] [--relay-pid PID].
//
// Server-side figures (RelayFigures) come from the in-process RelayCounters and the relay
// thread's CPU clock, or, for an external relay, from its Prometheus endpoint (GET /metrics,
// plain HTTP/1.0 over a blocking Asio TCP socket, text exposition parsed for the edgephys_*
// series below). The exporter has no process_* series, so an external relay's CPU comes from
// /proc/<pid>/stat (utime + stime) when --relay-pid is given, and is unknown (NaN, JSON null)
// otherwise. Counters are cumulative over the relay process's life and over all its rooms:
// scenarios take differences between two reads, and an external relay serving other traffic
// shows it in these figures.
#pragma once

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <thread>
#include <vector>

#include "loadgen/relay_process.h"  // MintJoinToken
#include "protocol/datagram_socket.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"

namespace CLI {
class App;
}  // namespace CLI

namespace edgephys::loadgen {

inline constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();

// --relay, --secret, --metrics, --relay-pid.
struct ExternalRelayOptions {
  std::string relay;    // "" : the scenario starts its relay in-process
  std::string secret;   // join token secret of the external relay
  std::string metrics;  // "" : the relay's host, port 9464; "off": no server-side figures
  int relay_pid = 0;    // 0: the external relay's CPU is unknown
  bool enabled() const { return !relay.empty(); }
};

void AddExternalRelayOptions(CLI::App& cmd, ExternalRelayOptions* options);
// "" or an error message (unparsable endpoints, --relay without --secret, ...).
std::string ValidateExternalRelay(const ExternalRelayOptions& options);
// A report's "relay" block for an external relay: external (true), address, metrics ("(relay
// host):9464" without --metrics) and cpu_source ("/proc/<pid>/stat", or "unknown" without
// --relay-pid).
nlohmann::json ExternalRelayJson(const ExternalRelayOptions& options);
// A report's note on an external relay's CPU figure: where it comes from, or why it is null.
const char* ExternalRelayCpuNote(const ExternalRelayOptions& options);

// A plain HTTP/1.0 GET of http://<host:port><path>; the body, or "" with *error set.
std::string HttpGet(const std::string& host_port, const std::string& path, double timeout_s,
                    std::string* error);

// Prometheus text exposition: series (name with its labels exactly as written, e.g.
// `edgephys_packets_rejected_total{reason="rate_limited"}`) -> value.
std::map<std::string, double> ParsePrometheusText(const std::string& text);
// The sum of every series named `name` (any labels); NaN if there is none.
double SumSeries(const std::map<std::string, double>& series, const std::string& name);

// /proc/<pid>/stat utime + stime in seconds; NaN if unreadable.
double ProcessCpuSeconds(int pid);

// One read of a relay's cumulative counters (NaN: unknown).
struct RelayFigures {
  bool ok = false;
  std::string error;
  double t = 0;  // steady seconds since the scenario's start
  double bytes_sent = 0, bytes_received = 0;
  double packets_sent = 0, packets_received = 0;
  double entity_updates_sent = 0, reliable_resends = 0;
  double physics_steps = 0, physics_step_seconds_sum = 0, physics_step_count = 0;
  double io_queue_drops = 0, send_errors = 0;
  double packets_rejected = 0;  // all reasons
  double rooms = kUnknown, clients = kUnknown;  // gauges
  double cpu_s = kUnknown;                      // relay CPU seconds (thread or process)
};

// The relay on its own thread, as edgephys-relay runs it (the in-process default of ccu and
// isolation).
struct RelayThread {
  RelayCounters counters;
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<Relay> relay;
  std::thread thread;
  std::atomic<bool> stop{false};
  std::atomic<double> cpu_s{0};
  std::chrono::steady_clock::time_point start;

  RelayThread(const RelayConfig& config, std::chrono::steady_clock::time_point t0);
  ~RelayThread();
};

class RelayTarget {
 public:
  // In-process: starts a RelayThread with `config` (its secret mints the tokens).
  RelayTarget(const RelayConfig& config, std::chrono::steady_clock::time_point t0);
  // External: the relay of `options` (validated).
  RelayTarget(const ExternalRelayOptions& options, std::chrono::steady_clock::time_point t0);
  ~RelayTarget();

  bool external() const { return !thread_; }
  const Endpoint& endpoint() const { return endpoint_; }
  // A signed token for `room` and `player_id`, valid for an hour.
  std::vector<uint8_t> Token(const std::string& room, uint32_t player_id) const;
  // The counters now. External: one scrape (a few ms on loopback); ok=false if it failed.
  RelayFigures Read() const;
  // In-process only (nullptr for an external relay).
  RelayThread* thread() const { return thread_.get(); }
  // The external relay's Prometheus HOST:PORT ("off": none); "" in-process.
  const std::string& metrics_address() const { return external_.metrics; }
  // Where relay CPU comes from: "relay thread", "/proc/<pid>" or "unknown".
  std::string cpu_source() const;
  // The "relay" object of a scenario's JSON: external or not, addresses, sources.
  nlohmann::json Describe() const;

 private:
  std::unique_ptr<RelayThread> thread_;
  ExternalRelayOptions external_;
  std::string secret_;
  Endpoint endpoint_;
  std::chrono::steady_clock::time_point t0_;
};

}  // namespace edgephys::loadgen
