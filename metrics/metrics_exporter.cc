#include "metrics/metrics_exporter.h"

#include <prometheus/client_metric.h>
#include <prometheus/collectable.h>
#include <httplib.h>
#include <prometheus/metric_family.h>
#include <prometheus/metric_type.h>
#include <prometheus/text_serializer.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cstddef>
#include <exception>
#include <limits>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "protocol/connection.h"
#include "metrics/http_gate.h"
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

// The families a relay exports, one kind of source each.
struct GaugeSource {
  static constexpr prometheus::MetricType kType = prometheus::MetricType::Gauge;
  RelayCounters::Gauge RelayCounters::*field;
};
// prometheus-cpp 1.0's text serializer writes the family name verbatim for counters (it adds no
// suffix), so a counter's name carries the one `_total` itself.
struct CounterSource {
  static constexpr prometheus::MetricType kType = prometheus::MetricType::Counter;
  RelayCounters::Counter RelayCounters::*field;
};
// One series per non-empty label; labels()[i] names counters(c)[i] (label name "reason").
struct ReasonCountersSource {
  static constexpr prometheus::MetricType kType = prometheus::MetricType::Counter;
  std::span<const RelayCounters::Counter> (*counters)(const RelayCounters&);
  const std::vector<std::string>& (*labels)();
};
using Histogram = decltype(RelayCounters::rtt_seconds);
struct HistogramSource {
  static constexpr prometheus::MetricType kType = prometheus::MetricType::Histogram;
  Histogram RelayCounters::*field;
};
// A gauge computed from the counters (not a stored field), e.g. a minimum across shards.
struct ComputedGaugeSource {
  static constexpr prometheus::MetricType kType = prometheus::MetricType::Gauge;
  double (RelayCounters::*compute)() const;
};
// Per-room work seconds (RoomWorkTimes): one series per tracked room, label "room".
struct RoomWorkSource {
  static constexpr prometheus::MetricType kType = prometheus::MetricType::Counter;
  RoomWorkTimes RelayCounters::*field;
};
using Source = std::variant<GaugeSource, CounterSource, ReasonCountersSource, HistogramSource,
                            ComputedGaugeSource, RoomWorkSource>;

struct FamilySpec {
  const char* name;
  const char* help;
  Source source;
};

template <auto kField>
std::span<const RelayCounters::Counter> CountersOf(const RelayCounters& c) {
  return c.*kField;
}

// Label per DropReason. Two series with one label set would make the whole scrape invalid:
// should DropReasonName() ever lag behind the enum (empty or repeated name), keep the
// exposition valid with a numbered label; metrics_test flags the mismatch.
const std::vector<std::string>& DropLabels() {
  static const std::vector<std::string> labels = [] {
    std::vector<std::string> out;
    for (size_t i = 0; i < kDropReasonCount; ++i) {
      std::string name(DropReasonName(static_cast<DropReason>(i)));
      if (name.empty() || std::find(out.begin(), out.end(), name) != out.end()) {
        name = "drop_reason_" + std::to_string(i);
      }
      out.push_back(std::move(name));
    }
    return out;
  }();
  return labels;
}

// Labels per schema enum value in snake_case; "none" is not a reason: its empty label skips the
// series.
template <typename Enum, size_t kCount>
const std::vector<std::string>& SchemaReasonLabels(const char* (*enum_name)(Enum)) {
  static const std::vector<std::string> labels = [&] {
    std::vector<std::string> out;
    for (size_t i = 0; i < kCount; ++i) {
      const auto reason = static_cast<Enum>(i);
      out.push_back(reason == Enum::None ? std::string() : SnakeCase(enum_name(reason)));
    }
    return out;
  }();
  return labels;
}
const std::vector<std::string>& RejectLabels() {
  return SchemaReasonLabels<schema::RejectReason, kRejectReasonCount>(
      schema::EnumNameRejectReason);
}
const std::vector<std::string>& DisconnectLabels() {
  return SchemaReasonLabels<schema::DisconnectReason, kDisconnectReasonCount>(
      schema::EnumNameDisconnectReason);
}

const std::vector<std::string>& BudgetLabels() {
  static const std::vector<std::string> labels = [] {
    std::vector<std::string> out;
    for (size_t i = 0; i < kBudgetKindCount; ++i) {
      out.emplace_back(BudgetKindName(static_cast<BudgetKind>(i)));
    }
    return out;
  }();
  return labels;
}

using C = RelayCounters;
// Exported in this order, after edgephys_build_info.
const FamilySpec kFamilies[] = {
    {"edgephys_rooms", "Rooms currently open.", GaugeSource{&C::rooms}},
    {"edgephys_clients", "Clients currently connected.", GaugeSource{&C::clients}},
    {"edgephys_entities", "Entities currently replicated.", GaugeSource{&C::entities}},
    {"edgephys_packets_received_total", "UDP datagrams received.",
     CounterSource{&C::packets_received}},
    {"edgephys_packets_sent_total", "UDP datagrams sent.", CounterSource{&C::packets_sent}},
    {"edgephys_bytes_received_total", "UDP payload bytes received.",
     CounterSource{&C::bytes_received}},
    {"edgephys_bytes_sent_total", "UDP payload bytes sent.", CounterSource{&C::bytes_sent}},
    {"edgephys_entity_updates_sent_total", "Entity states written into outgoing packets.",
     CounterSource{&C::entity_updates_sent}},
    {"edgephys_shared_bodies_cached_total",
     "Format-9 entity records whose body came from the room's per-tick cache (appended, not "
     "coded).",
     CounterSource{&C::shared_bodies_cached}},
    {"edgephys_shared_bodies_coded_total",
     "Format-9 entity records whose body the receiver's tick coded (first user of the body, or "
     "no free cache slot).",
     CounterSource{&C::shared_bodies_coded}},
    {"edgephys_lockstep_sends_total",
     "Lockstep rooms: canonical payloads sent as copies to receivers in lockstep.",
     CounterSource{&C::lockstep_sends}},
    {"edgephys_lockstep_leaves_total",
     "Lockstep rooms: receivers that left lockstep (a canonical payload not acknowledged within "
     "the ack ticks).",
     CounterSource{&C::lockstep_leaves}},
    {"edgephys_lockstep_rejoins_total",
     "Lockstep rooms: receivers that joined lockstep (their references matched the canonical "
     "stream's).",
     CounterSource{&C::lockstep_rejoins}},
    {"edgephys_lockstep_forced_keyframes_total",
     "Lockstep rooms: entities a rejoin made the canonical stream send as keyframes (records "
     "that differed from the joiner's).",
     CounterSource{&C::lockstep_forced_keyframes}},
    {"edgephys_entity_updates_received_total", "Entity states accepted from their owners.",
     CounterSource{&C::entity_updates_received}},
    {"edgephys_key_samples_strayed_total",
     "Key samples (--key-samples) found due because a receiver's straight line strayed from "
     "PhyS's states, per receiver.",
     CounterSource{&C::key_samples_strayed}},
    {"edgephys_key_samples_max_interval_total",
     "Key samples found due because the max interval passed (or none was sent), per receiver.",
     CounterSource{&C::key_samples_max_interval}},
    {"edgephys_reliable_resends_total", "Reliable units sent more than once.",
     CounterSource{&C::reliable_resends}},
    {"edgephys_reliable_messages_received_total",
     "Whole reliable messages received from clients.",
     CounterSource{&C::reliable_messages_received}},
    {"edgephys_connections_accepted_total", "Connections that completed the handshake.",
     CounterSource{&C::connections_accepted}},
    {"edgephys_send_errors_total", "Datagrams the socket refused to send.",
     CounterSource{&C::send_errors}},
    {"edgephys_io_queue_drops_total",
     "Datagrams dropped because their I/O thread's queue was full.",
     CounterSource{&C::io_queue_drops}},
    {"edgephys_packets_rejected_total", "Incoming datagrams dropped, by reason.",
     ReasonCountersSource{CountersOf<&C::packets_rejected>, DropLabels}},
    {"edgephys_entity_updates_rejected_total",
     "Entity updates dropped inside accepted packets, by reason.",
     ReasonCountersSource{CountersOf<&C::updates_rejected>, DropLabels}},
    {"edgephys_requests_rejected_total",
     "Connect, join and command requests refused to clients, by reason.",
     ReasonCountersSource{CountersOf<&C::requests_rejected>, RejectLabels}},
    {"edgephys_budget_refusals_total",
     "Spawns refused with Error{OverBudget}, by the room or player budget used up.",
     ReasonCountersSource{CountersOf<&C::budget_refusals>, BudgetLabels}},
    {"edgephys_disconnects_total", "Connections ended, by reason.",
     ReasonCountersSource{CountersOf<&C::disconnects>, DisconnectLabels}},
    {"edgephys_rtt_seconds", "Connection round-trip time samples, in seconds.",
     HistogramSource{&C::rtt_seconds}},
    {"edgephys_tick_duration_seconds", "Wall time of one room tick, in seconds.",
     HistogramSource{&C::tick_seconds}},
    {"edgephys_physics_bodies", "Rigid bodies in PhyS worlds (all rooms).",
     GaugeSource{&C::physics_bodies}},
    {"edgephys_physics_sleeping_bodies", "Dynamic bodies asleep in PhyS worlds (all rooms).",
     GaugeSource{&C::physics_sleeping_bodies}},
    {"edgephys_physics_workers", "Remote edgephys-phys workers attached.",
     GaugeSource{&C::physics_workers}},
    {"edgephys_physics_steps_total", "Fixed PhyS steps run (all rooms).",
     CounterSource{&C::physics_steps}},
    {"edgephys_physics_guard_resets_total", "Bodies restored by the stability guard.",
     CounterSource{&C::guard_resets}},
    {"edgephys_physics_failovers_total", "Rooms restored on another worker or embedded.",
     CounterSource{&C::physics_failovers}},
    {"edgephys_cluster_redis_errors_total",
     "Failed Redis round trips of the cluster directory (--redis): down, timeout, protocol.",
     CounterSource{&C::cluster_redis_errors}},
    {"edgephys_cluster_bad_keys_total", "Garbage met in the cluster's Redis keys, skipped.",
     CounterSource{&C::cluster_bad_keys}},
    {"edgephys_cluster_redirects_total",
     "Connects answered with a signed Redirect to the relay holding the room.",
     CounterSource{&C::cluster_redirects}},
    {"edgephys_cluster_rooms_restored_total",
     "Rooms of dead relays claimed and restored on this relay.",
     CounterSource{&C::cluster_rooms_restored}},
    {"edgephys_physics_step_seconds", "Wall time of one PhyS step, in seconds.",
     HistogramSource{&C::physics_step_seconds}},
    {"edgephys_physics_realtime_factor",
     "Simulated seconds per wall-clock second of the slowest room's embedded PhyS over its "
     "last ~1 s (below 1: that room simulates slower than real time); 1 without such a room.",
     ComputedGaugeSource{&C::PhysicsRealtimeFactor}},
    {"edgephys_room_update_seconds_total",
     "Seconds the relay worked for a room (its members' datagrams and connections, its PhyS "
     "results, its ticks), summed over the relay's threads; rooms past the cap summed in "
     "room=\"~other\".",
     RoomWorkSource{&C::room_work}},
    {"edgephys_bulk_datagrams_deferred_total",
     "Datagrams of bulk rooms' members handled after the light rooms' tick.",
     CounterSource{&C::bulk_datagrams_deferred}},
};

void AddMetrics(const GaugeSource& s, const RelayCounters& c, prometheus::MetricFamily* family) {
  prometheus::ClientMetric metric;
  metric.gauge.value = Load(c.*s.field);
  family->metric.push_back(std::move(metric));
}

void AddMetrics(const ComputedGaugeSource& s, const RelayCounters& c,
                prometheus::MetricFamily* family) {
  prometheus::ClientMetric metric;
  metric.gauge.value = (c.*s.compute)();
  family->metric.push_back(std::move(metric));
}

void AddMetrics(const RoomWorkSource& s, const RelayCounters& c, prometheus::MetricFamily* family) {
  for (const RoomWorkTimes::Series& series : (c.*s.field).Snapshot()) {
    prometheus::ClientMetric metric;
    metric.label.push_back({"room", series.label});
    metric.counter.value = series.seconds;
    family->metric.push_back(std::move(metric));
  }
}

void AddMetrics(const CounterSource& s, const RelayCounters& c, prometheus::MetricFamily* family) {
  prometheus::ClientMetric metric;
  metric.counter.value = Load(c.*s.field);
  family->metric.push_back(std::move(metric));
}

void AddMetrics(const ReasonCountersSource& s, const RelayCounters& c,
                prometheus::MetricFamily* family) {
  const std::span<const RelayCounters::Counter> counters = s.counters(c);
  const std::vector<std::string>& labels = s.labels();
  for (size_t i = 0; i < counters.size() && i < labels.size(); ++i) {
    if (labels[i].empty()) continue;
    prometheus::ClientMetric metric;
    metric.label.push_back({"reason", labels[i]});
    metric.counter.value = Load(counters[i]);
    family->metric.push_back(std::move(metric));
  }
}

// AtomicHistogram keeps non-cumulative buckets; Prometheus wants cumulative ones plus +Inf.
// _count is derived from the buckets so it always equals the +Inf bucket.
void AddMetrics(const HistogramSource& s, const RelayCounters& c,
                prometheus::MetricFamily* family) {
  const Histogram& histogram = c.*s.field;
  const size_t n = histogram.bounds().size();
  prometheus::ClientMetric metric;
  metric.histogram.bucket.reserve(n + 1);
  uint64_t cumulative = 0;
  for (size_t i = 0; i <= n; ++i) {
    cumulative += histogram.bucket(i);
    prometheus::ClientMetric::Bucket bucket;
    bucket.cumulative_count = cumulative;
    bucket.upper_bound = i < n ? histogram.bounds()[i] : std::numeric_limits<double>::infinity();
    metric.histogram.bucket.push_back(bucket);
  }
  metric.histogram.sample_count = cumulative;
  metric.histogram.sample_sum = histogram.sum();
  family->metric.push_back(std::move(metric));
}

class RelayCollectable : public prometheus::Collectable {
 public:
  explicit RelayCollectable(const RelayCounters* counters) : counters_(counters) {}

  std::vector<prometheus::MetricFamily> Collect() const override {
    std::vector<prometheus::MetricFamily> families;
    families.reserve(std::size(kFamilies) + 1);

    prometheus::MetricFamily info =
        Family("edgephys_build_info", "edgephys build information; the value is always 1.",
               prometheus::MetricType::Gauge);
    prometheus::ClientMetric metric;
    metric.label.push_back({"version", EDGEPHYS_VERSION});
    metric.gauge.value = 1;
    info.metric.push_back(std::move(metric));
    families.push_back(std::move(info));

    for (const FamilySpec& spec : kFamilies) {
      families.push_back(std::visit(
          [&](const auto& source) {
            prometheus::MetricFamily family = Family(spec.name, spec.help, source.kType);
            AddMetrics(source, *counters_, &family);
            return family;
          },
          spec.source));
    }
    return families;
  }

 private:
  const RelayCounters* counters_;  // not owned
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
  http::GateOptions options;
  // A bare "port" listens on every IPv4 address.
  options.address = bind_address.find(':') == std::string::npos ? "0.0.0.0:" + bind_address
                                                                 : bind_address;
  options.workers = 2;
  options.max_body_bytes = 0;
  auto gate = std::make_unique<http::HttpGate>(std::move(options));
  std::weak_ptr<prometheus::Collectable> weak = collectable;
  gate->routes().Get("/metrics", [weak](const httplib::Request&, httplib::Response& res) {
    auto source = weak.lock();
    if (!source) {
      res.status = 503;
      return;
    }
    res.set_content(prometheus::TextSerializer().Serialize(source->Collect()),
                    "text/plain; version=0.0.4; charset=utf-8");
  });
  if (Status st = gate->Start(); !st.ok()) {
    return Status(StatusCode::kIoError,
                  "metrics exporter: cannot listen on bind address: " + std::string(st.reason()));
  }
  const uint16_t port = gate->port();
  return std::unique_ptr<MetricsExporter>(
      new MetricsExporter(std::move(collectable), std::move(gate), port));
}

MetricsExporter::MetricsExporter(std::shared_ptr<prometheus::Collectable> collectable,
                                 std::unique_ptr<http::HttpGate> gate, uint16_t port)
    : collectable_(std::move(collectable)), gate_(std::move(gate)), port_(port) {}

MetricsExporter::~MetricsExporter() {
  // Stop the server (its workers joined) before the collectable goes away, so no scrape can
  // read `counters` after we return.
  gate_.reset();
  collectable_.reset();
}

}  // namespace edgephys
