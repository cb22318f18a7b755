// MetricsExporter: serves the relay's RelayCounters as Prometheus text exposition over HTTP
// (GET /metrics): prometheus-cpp's text format, served by metrics/http_gate.h (a whole-request
// deadline, connections capped per address and in total, so slow clients cannot starve
// scrapes).
//
// The relay never calls into prometheus-cpp. Its threads only bump the plain atomics in
// RelayCounters; the exporter reads them (relaxed loads) when a scrape arrives, on one of the
// HTTP server's own threads, and builds the metric families on the fly. A scrape therefore
// costs the relay nothing but cache traffic, and there is no per-metric registration.
//
// Exported metrics (all prefixed edgephys_; names, HELP texts and sources in the kFamilies table
// of metrics_exporter.cc):
//   gauges     rooms, clients, entities, build_info{version}, physics_bodies,
//              physics_sleeping_bodies, physics_workers
//   counters   packets_received_total, packets_sent_total, bytes_received_total,
//              bytes_sent_total, entity_updates_sent_total, entity_updates_received_total,
//              shared_bodies_cached_total, shared_bodies_coded_total (format 9),
//              lockstep_sends_total, lockstep_leaves_total, lockstep_rejoins_total,
//              lockstep_forced_keyframes_total,
//              reliable_resends_total, reliable_messages_received_total,
//              connections_accepted_total, send_errors_total, io_queue_drops_total,
//              packets_rejected_total{reason}, entity_updates_rejected_total{reason}
//                (reason = DropReasonName(), every reason exported, also at 0),
//              requests_rejected_total{reason}  (schema RejectReason in snake_case, no "none"),
//              disconnects_total{reason}        (DisconnectReason in snake_case, no "none"),
//              physics_steps_total, physics_guard_resets_total, physics_failovers_total,
//              bulk_datagrams_deferred_total,
//              room_update_seconds_total{room}  (relay/room_work_times.h: at most 128 rooms,
//                the rest summed in room="~other"; closed rooms' series removed)
//   histograms rtt_seconds, tick_duration_seconds, physics_step_seconds
//
// Consistency: one scrape is not an atomic snapshot of all counters (the relay keeps
// writing while it is read). Within a histogram, _count always equals the +Inf bucket and the
// buckets are cumulative; _sum may be off by the few observations made during the read.
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "protocol/status.h"
#include "relay/relay_counters.h"

namespace prometheus {
class Collectable;
}  // namespace prometheus

namespace edgephys::http {
class HttpGate;
}  // namespace edgephys::http

namespace edgephys {

class MetricsExporter {
 public:
  // Starts an HTTP server on `bind_address` serving GET /metrics.
  //
  // `bind_address` is one "host:port" (e.g. "0.0.0.0:9464", "127.0.0.1:0", "[::]:9464") or a
  // bare "port". Port 0 binds an ephemeral port; port() tells which one.
  // `counters` is not owned and must outlive the returned exporter; it is only read.
  //
  // Errors (nothing is left running on failure):
  //   kInvalidArgument  counters is null, bind_address is empty or lists several addresses
  //   kIoError          the server could not start (port in use, bad host, no permission)
  static Result<std::unique_ptr<MetricsExporter>> Start(const std::string& bind_address,
                                                        const RelayCounters* counters);

  // Stops the HTTP server and waits for in-flight scrapes to finish; after it returns the
  // exporter never touches `counters` again.
  ~MetricsExporter();

  MetricsExporter(const MetricsExporter&) = delete;
  MetricsExporter& operator=(const MetricsExporter&) = delete;

  // The TCP port actually bound (the ephemeral one when Start() was given port 0).
  uint16_t port() const { return port_; }

 private:
  MetricsExporter(std::shared_ptr<prometheus::Collectable> collectable,
                  std::unique_ptr<http::HttpGate> gate, uint16_t port);

  // The route holds only a weak_ptr to the collectable; we own it.
  std::shared_ptr<prometheus::Collectable> collectable_;
  std::unique_ptr<http::HttpGate> gate_;
  uint16_t port_;
};

// Thread-safety: Start() and the destructor must not race with each other on the same
// exporter; port() may be called from any thread. Scrapes are served concurrently with the
// relay's writes to `counters` by design.

}  // namespace edgephys
