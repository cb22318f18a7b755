// The relay's counters as the metrics exporter's source (metrics/metric_source.h): the relay
// fills the interface metrics/ declares, so metrics/ includes nothing from relay/.
//
// Exported families (all prefixed edgephys_; names, HELP texts and sources in the kFamilies
// table of relay_metrics.cc):
//   gauges     rooms, clients, entities, physics_bodies, physics_sleeping_bodies,
//              physics_workers, physics_realtime_factor
//   counters   packets_received_total, packets_sent_total, bytes_received_total,
//              bytes_sent_total, entity_updates_sent_total, entity_updates_received_total,
//              shared_bodies_cached_total, shared_bodies_coded_total (format 9),
//              reliable_resends_total,
//              reliable_messages_received_total, connections_accepted_total,
//              send_errors_total, io_queue_drops_total,
//              packets_rejected_total{reason}, entity_updates_rejected_total{reason}
//                (reason = DropReasonName(), every reason exported, also at 0),
//              requests_rejected_total{reason}  (schema RejectReason in snake_case, no "none"),
//              budget_refusals_total{reason}    (BudgetKindName),
//              disconnects_total{reason}        (DisconnectReason in snake_case, no "none"),
//              physics_steps_total, physics_guard_resets_total, physics_failovers_total,
//              cluster_*_total, bulk_datagrams_deferred_total,
//              room_update_seconds_total{room}  (relay/room_work_times.h: at most 128 rooms,
//                the rest summed in room="~other"; closed rooms' series removed)
//   histograms rtt_seconds, tick_duration_seconds, physics_step_seconds
// The exporter adds edgephys_build_info and the process_* families.
//
// Consistency: one scrape is not an atomic snapshot of all counters (the relay keeps writing
// while it is read). Within a histogram, the buckets are cumulative and +Inf is the count;
// the sum may be off by the few observations made during the read.
#pragma once

#include <memory>

#include "metrics/metric_source.h"
#include "relay/relay_counters.h"

namespace edgephys {

// A source reading `counters` (relaxed loads) at every scrape. `counters` is not owned and must
// outlive the source and the exporter holding it. Null counters: returns null (which
// MetricsExporter::Start refuses with kInvalidArgument).
std::shared_ptr<const MetricSource> RelayMetrics(const RelayCounters* counters);

}  // namespace edgephys
