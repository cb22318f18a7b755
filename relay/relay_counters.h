// RelayCounters: the relay's observable state as plain atomics. The relay's threads write
// them with relaxed increments (no locks, no allocation on the hot path); the Prometheus
// exporter (metrics/) and tests only read them. One instance per relay process.
#pragma once

#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <initializer_list>
#include <limits>

#include "protocol/connection.h"
#include "protocol/packet.h"
#include "relay/room_budget.h"
#include "relay/room_work_times.h"

namespace edgephys {

// Number of RejectReason values in schema/control.fbs (None .. BadProof).
inline constexpr size_t kRejectReasonCount = 24;
inline constexpr size_t kDisconnectReasonCount = 7;

// A fixed-bucket histogram safe to Observe() from one thread while others read it.
// Bounds are upper bucket limits in ascending order (Prometheus `le`), +Inf implied.
template <size_t N>
class AtomicHistogram {
 public:
  constexpr explicit AtomicHistogram(std::array<double, N> bounds) : bounds_(bounds) {}

  void Observe(double value) {
    size_t i = 0;
    while (i < N && value > bounds_[i]) ++i;
    buckets_[i].fetch_add(1, std::memory_order_relaxed);
    // Sum kept in nanounits to stay a lock-free integer add.
    sum_nano_.fetch_add(static_cast<int64_t>(value * 1e9), std::memory_order_relaxed);
  }

  const std::array<double, N>& bounds() const { return bounds_; }
  // Non-cumulative count of bucket i (i == N: above the last bound).
  uint64_t bucket(size_t i) const { return buckets_[i].load(std::memory_order_relaxed); }
  double sum() const { return static_cast<double>(sum_nano_.load(std::memory_order_relaxed)) / 1e9; }

 private:
  std::array<double, N> bounds_;
  std::array<std::atomic<uint64_t>, N + 1> buckets_{};
  std::atomic<int64_t> sum_nano_{0};
};

struct RelayCounters {
  using Counter = std::atomic<uint64_t>;
  using Gauge = std::atomic<int64_t>;

  static void Inc(Counter& c, uint64_t n = 1) { c.fetch_add(n, std::memory_order_relaxed); }
  static uint64_t Get(const Counter& c) { return c.load(std::memory_order_relaxed); }

  Gauge rooms{0};
  Gauge clients{0};
  Gauge entities{0};

  Counter packets_received{0};
  Counter packets_sent{0};
  Counter bytes_received{0};
  Counter bytes_sent{0};
  Counter entity_updates_sent{0};      // entity states written into outgoing packets
  Counter entity_updates_received{0};  // entity states accepted from owners
  // Format 9 rooms (ReplicationConfig::shared_encoding): entity records whose body a receiver
  // appended from the room's per-tick cache, and those it had to code (first user of a body,
  // or no free cache slot). cached / (cached + coded) is the sharing ratio.
  Counter shared_bodies_cached{0};
  Counter shared_bodies_coded{0};
  Counter reliable_resends{0};
  Counter reliable_messages_received{0};
  Counter connections_accepted{0};
  Counter send_errors{0};              // socket refused a datagram
  Counter io_queue_drops{0};           // datagrams dropped before a relay saw them: the
                                       // receive thread found their shard's queue full
                                       // (relay_shards.h; always 0 single-threaded)

  // Incoming datagrams dropped, by DropReason.
  std::array<Counter, static_cast<size_t>(DropReason::kCount)> packets_rejected{};
  // Individual entity updates dropped inside accepted packets (not owner, NaN...), by DropReason.
  std::array<Counter, static_cast<size_t>(DropReason::kCount)> updates_rejected{};
  // Connect / join / command refusals sent to clients, by schema RejectReason.
  std::array<Counter, kRejectReasonCount> requests_rejected{};
  // Connections ended, by DisconnectReason.
  std::array<Counter, kDisconnectReasonCount> disconnects{};
  // Spawns and property writes refused with Error{OverBudget}, by the budget used up
  // (BudgetKind).
  std::array<Counter, kBudgetKindCount> budget_refusals{};
  // Property writes (RoomHost::SetProperty): accepted and broadcast, and compare-and-set writes
  // that lost (answered with PropertyConflict). Refused ones count in requests_rejected.
  Counter property_writes{0};
  Counter property_conflicts{0};
  // Ownership (relay/room_ownership.cc): changes of an entity's owner (requests granted, hand
  // overs, releases, a leaving owner's persistent entities passing to the room), and states
  // dropped because their sender owned the entity before its latest change (late states of a
  // previous owner; also counted in updates_rejected as not_owner).
  Counter ownership_changes{0};
  Counter stale_owner_states{0};

  // PhyS (embedded worlds, all rooms).
  Counter physics_steps{0};
  Counter guard_resets{0};         // stability-guard restores
  Gauge physics_bodies{0};
  Gauge physics_sleeping_bodies{0};
  Gauge physics_workers{0};        // remote edgephys-phys workers attached
  Counter physics_failovers{0};    // rooms restored after a worker died

  // Clusters of relays (--redis; relay/cluster_hook.h), published every update.
  Counter cluster_redis_errors{0};    // failed Redis round trips (down, timeout)
  Counter cluster_bad_keys{0};        // garbage met in Redis keys, skipped
  Counter cluster_redirects{0};       // Connects answered with a signed Redirect
  Counter cluster_rooms_restored{0};  // rooms of dead relays restored here
  AtomicHistogram<10> physics_step_seconds{
      {0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.016, 0.025, 0.05}};
  // Real-time factor of embedded PhyS (PhysicsLink::realtime_factor(): simulated seconds per
  // second over a room's last completed window of about a second) of the slowest room. Each
  // relay stores the minimum over its rooms every update in its own slot (its shard index; a
  // standalone relay slot 0), NaN when it has none measured yet. PhysicsRealtimeFactor() is
  // the minimum over the slots, 1 when no room has one: edgephys_physics_realtime_factor.
  static constexpr size_t kRealtimeFactorSlots = 64;  // RelayShards::kMaxShards
  struct RealtimeFactorSlot {
    std::atomic<double> value{std::numeric_limits<double>::quiet_NaN()};
  };
  std::array<RealtimeFactorSlot, kRealtimeFactorSlots> physics_realtime_factor{};

  // Round-trip time samples (seconds), one per connection per second.
  AtomicHistogram<10> rtt_seconds{{0.0005, 0.001, 0.0025, 0.005, 0.01, 0.025, 0.05, 0.1, 0.25, 0.5}};
  // Wall time of one room tick (seconds).
  AtomicHistogram<10> tick_seconds{
      {0.00001, 0.00005, 0.0001, 0.00025, 0.0005, 0.001, 0.0025, 0.005, 0.01, 0.05}};
  // Seconds of relay work per room (relay/room_work_times.h): edgephys_room_update_seconds_total.
  RoomWorkTimes room_work;
  // Partial reliable messages of clients (Connection::reliable_partial_bytes(), all shards): bytes
  // held now, and connections ended because the sum passed AbuseLimits::max_reassembly_bytes
  // (the largest holder goes; relay/relay.h).
  Gauge reassembly_held_bytes{0};
  Counter reassembly_evictions{0};
  // Datagrams of bulk rooms' members handled after the light rooms' tick (Relay::Update).
  Counter bulk_datagrams_deferred{0};

  void RejectPacket(DropReason r) { Inc(packets_rejected[static_cast<size_t>(r)]); }
  void RejectUpdate(DropReason r) { Inc(updates_rejected[static_cast<size_t>(r)]); }
  void RejectRequest(uint16_t reject_reason) {
    if (reject_reason < kRejectReasonCount) Inc(requests_rejected[reject_reason]);
  }
  void RefuseOverBudget(BudgetKind kind) {
    if (static_cast<size_t>(kind) < kBudgetKindCount) Inc(budget_refusals[static_cast<size_t>(kind)]);
  }
  void CountDisconnect(DisconnectReason r) {
    size_t i = static_cast<size_t>(r);
    if (i < kDisconnectReasonCount) Inc(disconnects[i]);
  }
  void PublishRealtimeFactor(uint32_t slot, double slowest_room) {
    physics_realtime_factor[slot % kRealtimeFactorSlots].value.store(slowest_room,
                                                                     std::memory_order_relaxed);
  }
  double PhysicsRealtimeFactor() const {
    double slowest = std::numeric_limits<double>::quiet_NaN();
    for (const RealtimeFactorSlot& s : physics_realtime_factor) {
      slowest = std::fmin(slowest, s.value.load(std::memory_order_relaxed));  // NaN: ignored
    }
    return std::isnan(slowest) ? 1.0 : slowest;
  }
};

}  // namespace edgephys
