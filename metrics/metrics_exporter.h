// MetricsExporter: serves a MetricSource (metrics/metric_source.h; the relay's is
// relay/relay_metrics.h) as Prometheus text exposition over HTTP (GET /metrics), served by
// metrics/http_gate.h (a whole-request deadline, connections capped per address and in total,
// so slow clients cannot starve scrapes).
//
// The source's owner never calls into prometheus-cpp: the exporter asks the source for its
// families when a scrape arrives, on one of the HTTP server's own threads, and converts them.
// Every scrape also carries edgephys_build_info{version} and the process_* families of
// metrics/process_metrics.h (CPU seconds, resident and virtual memory, open and maximum
// descriptors, start time, threads).
#pragma once

#include <cstdint>
#include <memory>
#include <string>

#include "protocol/status.h"
#include "metrics/metric_source.h"

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
  // The exporter shares ownership of `source` and reads it on its HTTP threads.
  //
  // Errors (nothing is left running on failure):
  //   kInvalidArgument  source is null, bind_address is empty or lists several addresses
  //   kIoError          the server could not start (port in use, bad host, no permission)
  static Result<std::unique_ptr<MetricsExporter>> Start(const std::string& bind_address,
                                                        std::shared_ptr<const MetricSource> source);

  // Stops the HTTP server and waits for in-flight scrapes to finish; after it returns the
  // exporter never touches the source again.
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
// source's writers by design (MetricSource::Collect).

}  // namespace edgephys
