// RelayMetrics: the relay's RelayCounters as the exporter's MetricSource (the table of
// exported families, their names and HELP texts).
#include "relay/relay_metrics.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <cctype>
#include <cstddef>
#include <span>
#include <string>
#include <string_view>
#include <utility>
#include <variant>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "protocol/connection.h"
#include "protocol/packet.h"

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


// The families a relay exports, one kind of source each.
struct GaugeSource {
  static constexpr MetricKind kType = MetricKind::kGauge;
  RelayCounters::Gauge RelayCounters::*field;
};
// prometheus-cpp 1.0's text serializer writes the family name verbatim for counters (it adds no
// suffix), so a counter's name carries the one `_total` itself.
struct CounterSource {
  static constexpr MetricKind kType = MetricKind::kCounter;
  RelayCounters::Counter RelayCounters::*field;
};
// One series per non-empty label; labels()[i] names counters(c)[i] (label name "reason").
struct ReasonCountersSource {
  static constexpr MetricKind kType = MetricKind::kCounter;
  std::span<const RelayCounters::Counter> (*counters)(const RelayCounters&);
  const std::vector<std::string>& (*labels)();
};
using Histogram = decltype(RelayCounters::rtt_seconds);
struct HistogramSource {
  static constexpr MetricKind kType = MetricKind::kHistogram;
  Histogram RelayCounters::*field;
};
// A gauge computed from the counters (not a stored field), e.g. a minimum across shards.
struct ComputedGaugeSource {
  static constexpr MetricKind kType = MetricKind::kGauge;
  double (RelayCounters::*compute)() const;
};
// Per-room work seconds (RoomWorkTimes): one series per tracked room, label "room".
struct RoomWorkSource {
  static constexpr MetricKind kType = MetricKind::kCounter;
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
    {"edgephys_entity_updates_received_total", "Entity states accepted from their owners.",
     CounterSource{&C::entity_updates_received}},
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
     "Spawns and property writes refused with Error{OverBudget}, by the room or player budget "
     "used up.",
     ReasonCountersSource{CountersOf<&C::budget_refusals>, BudgetLabels}},
    {"edgephys_property_writes_total",
     "Room and entity property writes accepted and sent to the room's members.",
     CounterSource{&C::property_writes}},
    {"edgephys_property_conflicts_total",
     "Property compare-and-set writes that expected another version (answered with the current "
     "value).",
     CounterSource{&C::property_conflicts}},
    {"edgephys_ownership_changes_total",
     "Changes of an entity's owner: requests granted, hand overs, releases, and a leaving "
     "owner's persistent entities passing to the room.",
     CounterSource{&C::ownership_changes}},
    {"edgephys_stale_owner_states_total",
     "Entity states dropped because their sender was the entity's owner before its latest "
     "ownership change (also in edgephys_entity_updates_rejected_total{reason=\"not_owner\"}).",
     CounterSource{&C::stale_owner_states}},
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
    {"edgephys_reassembly_held_bytes",
     "Bytes held for clients' partial reliable messages (reassembly and out-of-order units).",
     GaugeSource{&C::reassembly_held_bytes}},
    {"edgephys_reassembly_evictions_total",
     "Connections ended because the bytes held for partial messages passed "
     "--max-reassembly-bytes (the largest holder goes).",
     CounterSource{&C::reassembly_evictions}},
    {"edgephys_bulk_datagrams_deferred_total",
     "Datagrams of bulk rooms' members handled after the light rooms' tick.",
     CounterSource{&C::bulk_datagrams_deferred}},
};

void AddMetrics(const GaugeSource& s, const RelayCounters& c, MetricFamilyData* family) {
  family->samples.push_back({{}, Load(c.*s.field)});
}

void AddMetrics(const ComputedGaugeSource& s, const RelayCounters& c,
                MetricFamilyData* family) {
  family->samples.push_back({{}, (c.*s.compute)()});
}

void AddMetrics(const RoomWorkSource& s, const RelayCounters& c, MetricFamilyData* family) {
  for (const RoomWorkTimes::Series& series : (c.*s.field).Snapshot()) {
    family->samples.push_back({{{"room", series.label}}, series.seconds});
  }
}

void AddMetrics(const CounterSource& s, const RelayCounters& c, MetricFamilyData* family) {
  family->samples.push_back({{}, Load(c.*s.field)});
}

void AddMetrics(const ReasonCountersSource& s, const RelayCounters& c,
                MetricFamilyData* family) {
  const std::span<const RelayCounters::Counter> counters = s.counters(c);
  const std::vector<std::string>& labels = s.labels();
  for (size_t i = 0; i < counters.size() && i < labels.size(); ++i) {
    if (labels[i].empty()) continue;
    family->samples.push_back({{{"reason", labels[i]}}, Load(counters[i])});
  }
}

// AtomicHistogram keeps non-cumulative buckets; Prometheus wants cumulative ones plus +Inf.
// The exporter derives _count from the +Inf bucket.
void AddMetrics(const HistogramSource& s, const RelayCounters& c,
                MetricFamilyData* family) {
  const Histogram& histogram = c.*s.field;
  const size_t n = histogram.bounds().size();
  MetricHistogram out;
  out.bounds.assign(histogram.bounds().begin(), histogram.bounds().end());
  out.cumulative.reserve(n + 1);
  uint64_t cumulative = 0;
  for (size_t i = 0; i <= n; ++i) {
    cumulative += histogram.bucket(i);
    out.cumulative.push_back(cumulative);
  }
  out.sum = histogram.sum();
  family->histograms.push_back(std::move(out));
}

class RelayMetricSource final : public MetricSource {
 public:
  explicit RelayMetricSource(const RelayCounters* counters) : counters_(counters) {}

  void Collect(std::vector<MetricFamilyData>* out) const override {
    out->reserve(out->size() + std::size(kFamilies));
    for (const FamilySpec& spec : kFamilies) {
      out->push_back(std::visit(
          [&](const auto& source) {
            MetricFamilyData family;
            family.name = spec.name;
            family.help = spec.help;
            family.kind = source.kType;
            AddMetrics(source, *counters_, &family);
            return family;
          },
          spec.source));
    }
  }

 private:
  const RelayCounters* counters_;  // not owned
};

}  // namespace

std::shared_ptr<const MetricSource> RelayMetrics(const RelayCounters* counters) {
  if (counters == nullptr) return nullptr;
  return std::make_shared<RelayMetricSource>(counters);
}

}  // namespace edgephys
