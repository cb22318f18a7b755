#include "metrics/metrics_exporter.h"

#include <prometheus/client_metric.h>
#include <prometheus/collectable.h>
#include <prometheus/exposer.h>
#include <prometheus/metric_family.h>
#include <prometheus/metric_type.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cstddef>
#include <exception>
#include <limits>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "protocol/connection.h"
#include "protocol/packet.h"

#ifndef EDGEPHYS_VERSION
#define EDGEPHYS_VERSION "0.1.0"
#endif

namespace edgephys {
namespace {

// The counter arrays in RelayCounters are indexed by the schema / protocol enums; catch any
// drift at compile time rather than exporting mislabelled series.
static_assert(kRejectReasonCount ==
                  static_cast<size_t>(schema::RejectReason::MAX) + 1,
              "kRejectReasonCount out of sync with schema/control.fbs RejectReason");
static_assert(kDisconnectReasonCount ==
                  static_cast<size_t>(schema::DisconnectReason::MAX) + 1,
              "kDisconnectReasonCount out of sync with schema/control.fbs DisconnectReason");
static_assert(static_cast<size_t>(DisconnectReason::kReliableOverflow) + 1 ==
                  kDisconnectReasonCount,
              "protocol DisconnectReason out of sync with kDisconnectReasonCount");

constexpr size_t kDropReasonCount = static_cast<size_t>(DropReason::kCount);

// "BadToken" -> "bad_token".
std::string SnakeCase(std::string_view camel) {
  std::string out;
  out.reserve(camel.size() + 4);
  for (char c : camel) {
    const auto uc = static_cast<unsigned char>(c);
    if (std::isupper(uc)) {
      if (!out.empty()) out.push_back('_');
      out.push_back(static_cast<char>(std::tolower(uc)));
    } else {
      out.push_back(c);
    }
  }
  return out;
}

double Load(const RelayCounters::Counter& c) {
  return static_cast<double>(c.load(std::memory_order_relaxed));
}
double Load(const RelayCounters::Gauge& g) {
  return static_cast<double>(g.load(std::memory_order_relaxed));
}

prometheus::MetricFamily Family(std::string name, std::string help, prometheus::MetricType type) {
  prometheus::MetricFamily family;
  family.name = std::move(name);
  family.help = std::move(help);
  family.type = type;
  return family;
}

prometheus::MetricFamily GaugeFamily(std::string name, std::string help,
                                     const RelayCounters::Gauge& gauge) {
  prometheus::MetricFamily family =
      Family(std::move(name), std::move(help), prometheus::MetricType::Gauge);
  prometheus::ClientMetric metric;
  metric.gauge.value = Load(gauge);
  family.metric.push_back(std::move(metric));
  return family;
}

// prometheus-cpp 1.0's text serializer writes the family name verbatim for counters (it adds no
// suffix), so `name` carries the one `_total` itself.
prometheus::MetricFamily CounterFamily(std::string name, std::string help,
                                       const RelayCounters::Counter& counter) {
  prometheus::MetricFamily family =
      Family(std::move(name), std::move(help), prometheus::MetricType::Counter);
  prometheus::ClientMetric metric;
  metric.counter.value = Load(counter);
  family.metric.push_back(std::move(metric));
  return family;
}

// One series per entry of `labels` that is non-empty; labels[i] names counters[i].
template <size_t N>
prometheus::MetricFamily LabeledCounterFamily(std::string name, std::string help,
                                              const std::array<RelayCounters::Counter, N>& counters,
                                              const std::vector<std::string>& labels) {
  prometheus::MetricFamily family =
      Family(std::move(name), std::move(help), prometheus::MetricType::Counter);
  for (size_t i = 0; i < N && i < labels.size(); ++i) {
    if (labels[i].empty()) continue;
    prometheus::ClientMetric metric;
    metric.label.push_back({"reason", labels[i]});
    metric.counter.value = Load(counters[i]);
    family.metric.push_back(std::move(metric));
  }
  return family;
}

// AtomicHistogram keeps non-cumulative buckets; Prometheus wants cumulative ones plus +Inf.
// _count is derived from the buckets so it always equals the +Inf bucket.
template <size_t N>
prometheus::MetricFamily HistogramFamily(std::string name, std::string help,
                                         const AtomicHistogram<N>& histogram) {
  prometheus::MetricFamily family =
      Family(std::move(name), std::move(help), prometheus::MetricType::Histogram);
  prometheus::ClientMetric metric;
  metric.histogram.bucket.reserve(N + 1);
  uint64_t cumulative = 0;
  for (size_t i = 0; i <= N; ++i) {
    cumulative += histogram.bucket(i);
    prometheus::ClientMetric::Bucket bucket;
    bucket.cumulative_count = cumulative;
    bucket.upper_bound =
        i < N ? histogram.bounds()[i] : std::numeric_limits<double>::infinity();
    metric.histogram.bucket.push_back(bucket);
  }
  metric.histogram.sample_count = cumulative;
  metric.histogram.sample_sum = histogram.sum();
  family.metric.push_back(std::move(metric));
  return family;
}

class RelayCollectable : public prometheus::Collectable {
 public:
  explicit RelayCollectable(const RelayCounters* counters) : counters_(counters) {
    drop_labels_.reserve(kDropReasonCount);
    for (size_t i = 0; i < kDropReasonCount; ++i) {
      std::string name(DropReasonName(static_cast<DropReason>(i)));
      // Two series with one label set would make the whole scrape invalid. Should
      // DropReasonName() ever lag behind the enum (empty or repeated name), keep the exposition
      // valid with a numbered label; metrics_test flags the mismatch.
      if (name.empty() ||
          std::find(drop_labels_.begin(), drop_labels_.end(), name) != drop_labels_.end()) {
        name = "drop_reason_" + std::to_string(i);
      }
      drop_labels_.push_back(std::move(name));
    }
    reject_labels_.reserve(kRejectReasonCount);
    for (size_t i = 0; i < kRejectReasonCount; ++i) {
      const auto reason = static_cast<schema::RejectReason>(i);
      // "none" is not a rejection; an empty label skips the series.
      reject_labels_.push_back(reason == schema::RejectReason::None
                                   ? std::string()
                                   : SnakeCase(schema::EnumNameRejectReason(reason)));
    }
    disconnect_labels_.reserve(kDisconnectReasonCount);
    for (size_t i = 0; i < kDisconnectReasonCount; ++i) {
      const auto reason = static_cast<schema::DisconnectReason>(i);
      disconnect_labels_.push_back(reason == schema::DisconnectReason::None
                                       ? std::string()
                                       : SnakeCase(schema::EnumNameDisconnectReason(reason)));
    }
  }

  std::vector<prometheus::MetricFamily> Collect() const override {
    const RelayCounters& c = *counters_;
    std::vector<prometheus::MetricFamily> families;
    families.reserve(24);

    {
      prometheus::MetricFamily info =
          Family("edgephys_build_info", "edgephys build information; the value is always 1.",
                 prometheus::MetricType::Gauge);
      prometheus::ClientMetric metric;
      metric.label.push_back({"version", EDGEPHYS_VERSION});
      metric.gauge.value = 1;
      info.metric.push_back(std::move(metric));
      families.push_back(std::move(info));
    }

    families.push_back(GaugeFamily("edgephys_rooms", "Rooms currently open.", c.rooms));
    families.push_back(
        GaugeFamily("edgephys_clients", "Clients currently connected.", c.clients));
    families.push_back(GaugeFamily("edgephys_entities", "Entities currently replicated.",
                                   c.entities));

    families.push_back(CounterFamily("edgephys_packets_received_total",
                                     "UDP datagrams received.", c.packets_received));
    families.push_back(CounterFamily("edgephys_packets_sent_total", "UDP datagrams sent.",
                                     c.packets_sent));
    families.push_back(CounterFamily("edgephys_bytes_received_total",
                                     "UDP payload bytes received.", c.bytes_received));
    families.push_back(
        CounterFamily("edgephys_bytes_sent_total", "UDP payload bytes sent.", c.bytes_sent));
    families.push_back(CounterFamily("edgephys_entity_updates_sent_total",
                                     "Entity states written into outgoing packets.",
                                     c.entity_updates_sent));
    families.push_back(CounterFamily("edgephys_shared_bodies_cached_total",
                                     "Format-9 entity records whose body came from the room's "
                                     "per-tick cache (appended, not coded).",
                                     c.shared_bodies_cached));
    families.push_back(CounterFamily("edgephys_shared_bodies_coded_total",
                                     "Format-9 entity records whose body the receiver's tick "
                                     "coded (first user of the body, or no free cache slot).",
                                     c.shared_bodies_coded));
    families.push_back(CounterFamily("edgephys_entity_updates_received_total",
                                     "Entity states accepted from their owners.",
                                     c.entity_updates_received));
    families.push_back(CounterFamily("edgephys_reliable_resends_total",
                                     "Reliable units sent more than once.",
                                     c.reliable_resends));
    families.push_back(CounterFamily("edgephys_reliable_messages_received_total",
                                     "Whole reliable messages received from clients.",
                                     c.reliable_messages_received));
    families.push_back(CounterFamily("edgephys_connections_accepted_total",
                                     "Connections that completed the handshake.",
                                     c.connections_accepted));
    families.push_back(CounterFamily("edgephys_send_errors_total",
                                     "Datagrams the socket refused to send.", c.send_errors));
    families.push_back(CounterFamily("edgephys_io_queue_drops_total",
                                     "Datagrams dropped because their I/O thread's queue was full.",
                                     c.io_queue_drops));

    families.push_back(LabeledCounterFamily("edgephys_packets_rejected_total",
                                            "Incoming datagrams dropped, by reason.",
                                            c.packets_rejected, drop_labels_));
    families.push_back(LabeledCounterFamily(
        "edgephys_entity_updates_rejected_total",
        "Entity updates dropped inside accepted packets, by reason.", c.updates_rejected,
        drop_labels_));
    families.push_back(LabeledCounterFamily(
        "edgephys_requests_rejected_total",
        "Connect, join and command requests refused to clients, by reason.",
        c.requests_rejected, reject_labels_));
    families.push_back(LabeledCounterFamily("edgephys_disconnects_total",
                                            "Connections ended, by reason.", c.disconnects,
                                            disconnect_labels_));

    families.push_back(HistogramFamily("edgephys_rtt_seconds",
                                       "Connection round-trip time samples, in seconds.",
                                       c.rtt_seconds));
    families.push_back(HistogramFamily("edgephys_tick_duration_seconds",
                                       "Wall time of one room tick, in seconds.",
                                       c.tick_seconds));

    families.push_back(GaugeFamily("edgephys_physics_bodies",
                                   "Rigid bodies in PhyS worlds (all rooms).", c.physics_bodies));
    families.push_back(GaugeFamily("edgephys_physics_sleeping_bodies",
                                   "Dynamic bodies asleep in PhyS worlds (all rooms).",
                                   c.physics_sleeping_bodies));
    families.push_back(GaugeFamily("edgephys_physics_workers",
                                   "Remote edgephys-phys workers attached.", c.physics_workers));
    families.push_back(CounterFamily("edgephys_physics_steps_total",
                                     "Fixed PhyS steps run (all rooms).", c.physics_steps));
    families.push_back(CounterFamily("edgephys_physics_guard_resets_total",
                                     "Bodies restored by the stability guard.", c.guard_resets));
    families.push_back(CounterFamily("edgephys_physics_failovers_total",
                                     "Rooms restored on another worker or embedded.",
                                     c.physics_failovers));
    families.push_back(HistogramFamily("edgephys_physics_step_seconds",
                                       "Wall time of one PhyS step, in seconds.",
                                       c.physics_step_seconds));
    return families;
  }

 private:
  const RelayCounters* counters_;  // not owned
  std::vector<std::string> drop_labels_;
  std::vector<std::string> reject_labels_;      // empty string: not exported
  std::vector<std::string> disconnect_labels_;  // empty string: not exported
};

}  // namespace

Result<std::unique_ptr<MetricsExporter>> MetricsExporter::Start(const std::string& bind_address,
                                                                const RelayCounters* counters) {
  if (counters == nullptr) {
    return Status(StatusCode::kInvalidArgument, "metrics exporter: counters is null");
  }
  if (bind_address.empty() || bind_address.find(',') != std::string::npos) {
    return Status(StatusCode::kInvalidArgument,
                  "metrics exporter: bind address must be one host:port");
  }

  auto collectable = std::make_shared<RelayCollectable>(counters);
  std::unique_ptr<prometheus::Exposer> exposer;
  try {
    exposer = std::make_unique<prometheus::Exposer>(bind_address);
  } catch (const std::exception&) {
    // civetweb reports bind failures (port in use, bad host, privileged port) by throwing.
    return Status(StatusCode::kIoError, "metrics exporter: cannot listen on bind address");
  }
  const std::vector<int> ports = exposer->GetListeningPorts();
  if (ports.empty() || ports.front() <= 0 || ports.front() > 65535) {
    return Status(StatusCode::kIoError, "metrics exporter: server reports no listening port");
  }
  exposer->RegisterCollectable(collectable);

  return std::unique_ptr<MetricsExporter>(new MetricsExporter(
      std::move(collectable), std::move(exposer), static_cast<uint16_t>(ports.front())));
}

MetricsExporter::MetricsExporter(std::shared_ptr<prometheus::Collectable> collectable,
                                 std::unique_ptr<prometheus::Exposer> exposer, uint16_t port)
    : collectable_(std::move(collectable)), exposer_(std::move(exposer)), port_(port) {}

MetricsExporter::~MetricsExporter() {
  // Stop the server (civetweb joins its worker threads) before the collectable goes away, so
  // no scrape can read `counters` after we return.
  exposer_.reset();
  collectable_.reset();
}

}  // namespace edgephys
