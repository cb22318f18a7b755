#include "relay/replication.h"

#include <algorithm>
#include <cmath>

#include "relay/entity.h"
#include "relay/entity_streams.h"

namespace edgephys {
namespace {

constexpr uint32_t kFlagAvatar = 1u << 3;  // schema::EntityFlags::Avatar
constexpr uint32_t kFlagHand = 1u << 4;    // schema::EntityFlags::Hand
// Entities assumed per datagram when estimating a selection's size.
constexpr size_t kEntitiesPerPacketEstimate = 64;

double Weight(PriorityClass c) {
  switch (c) {
    case PriorityClass::kCritical: return 4.0;
    case PriorityClass::kNormal: return 1.0;
    case PriorityClass::kAmbient: return 0.75;
    case PriorityClass::kResting: return 0.5;
  }
  return 1.0;
}

}  // namespace

QuantizationConfig QuantizationOf(const ReplicationConfig& config) {
  QuantizationConfig q;
  float h = config.bounds_half_extent_m;
  q.bounds_min = {-h, -h, -h};
  q.bounds_max = {h, h, h};
  q.position_step_m = config.position_step_m;
  q.rotation_error_deg = config.rotation_bound_deg;
  return q;
}

ClientReplicator::ClientReplicator(const ReplicationConfig& config)
    : config_(config), payload_(kMaxUnreliablePayload), stream_(NewEntityStream(config_)) {
  soft_ = std::make_unique<SoftDeltaSender>(
      SoftDeltaSenderConfig{config_.position_step_m, config_.position_threshold_m});
  candidates_.reserve(256);
}

ClientReplicator::~ClientReplicator() = default;

PriorityClass ClientReplicator::ClassOf(const Entity& e, double now) const {
  if ((e.flags & (kFlagAvatar | kFlagHand)) || e.held_by != 0) return PriorityClass::kCritical;
  if (now - e.changed_at > config_.resting_after_s) return PriorityClass::kResting;
  if (e.physics == PhysicsRole::kSimulated && e.touching == 0 &&
      now - e.interacted_at > config_.interaction_linger_s) {
    return PriorityClass::kAmbient;
  }
  return PriorityClass::kNormal;
}

double ClientReplicator::IntervalOf(PriorityClass c) const {
  if (config_.fixed_rate_hz > 0) return 1.0 / config_.fixed_rate_hz;
  switch (c) {
    case PriorityClass::kCritical: return 1.0 / config_.critical_hz;
    case PriorityClass::kAmbient: return 1.0 / config_.ambient_hz;
    default: return 1.0 / config_.normal_hz;
  }
}


void ClientReplicator::Tick(const ReplicationFrame& frame, uint32_t self, double now,
                            Connection& connection, PacketWriter& out, RelayCounters& counters) {
  double dt = last_tick_ < 0 ? 0 : now - last_tick_;
  last_tick_ = now;
  time_ms_ = static_cast<uint32_t>(static_cast<uint64_t>(now * 1000.0));
  const bool budgeted = config_.bandwidth_budget_bytes_per_s > 0;
  if (budgeted) {
    // Unused budget carries over for at most a quarter second (bounded bursts).
    budget_bytes_ = std::min(budget_bytes_ + config_.bandwidth_budget_bytes_per_s * dt,
                             config_.bandwidth_budget_bytes_per_s * 0.25 + kMaxPacketSize);
  }
  const double resend_after = connection.stats().rtt_s * 1.25 + 0.05;
  TickSoftBodies(frame, self, now, resend_after, connection, out, counters);
  TickEntities(frame, self, now, resend_after, connection, out, counters);
}

void ClientReplicator::TickEntities(const ReplicationFrame& frame, uint32_t self, double now,
                                    double resend_after, Connection& connection,
                                    PacketWriter& out, RelayCounters& counters) {
  const bool budgeted = config_.bandwidth_budget_bytes_per_s > 0;
  candidates_.clear();
  // The walk below is bound by loading this receiver's per-entity records (views_, the format-9
  // stream's tracks) from beyond the core's cache: start loading them a few entities ahead.
  constexpr size_t kPrefetchAhead = 8;
  const size_t entity_count = frame.by_id.size();
  for (size_t i = 0; i < entity_count; ++i) {  // by id: candidates_ come out in id order
    if (i + kPrefetchAhead < entity_count) {
      const uint32_t ahead = frame.by_id[i + kPrefetchAhead]->slot;
      if (ahead < views_.size()) {
        __builtin_prefetch(&views_[ahead]);
        __builtin_prefetch(reinterpret_cast<const char*>(&views_[ahead]) + sizeof(View) - 1);
      }
      stream_->Prefetch(ahead);
    }
    const Entity& e = *frame.by_id[i];
    const uint32_t id = e.id;
    if (e.owner == self) continue;
    View& v = ViewOf(e);
    if (now + kEpsilon < v.next_due || v.settled_version == e.version) continue;
    PriorityClass cls = ClassOf(e, now);
    uint8_t fields = kFieldPosition | kFieldRotation;
    const StreamNeed need = stream_->Want(StreamView(e), now, resend_after, &fields);
    if (need == StreamNeed::kSettled) v.settled_version = e.version;
    if (need != StreamNeed::kSend) continue;
    double waiting = std::max(now - v.last_sent, IntervalOf(cls));
    candidates_.push_back({Weight(cls) * std::min(waiting, 60.0), id, &e, fields});
  }
  if (candidates_.empty()) return;
  // Without a budget every candidate goes, already in id order (the delta formats code ids as
  // increasing gaps). With one: take the most urgent while the budget allows (by the running
  // size estimate), then encode them in id order.
  if (budgeted) {
    std::sort(candidates_.begin(), candidates_.end(), [](const Candidate& a, const Candidate& b) {
      return a.priority != b.priority ? a.priority > b.priority : a.id < b.id;
    });
    selected_.clear();
    double estimate = 0;
    for (const Candidate& c : candidates_) {
      double cost = bytes_per_entity_ + (selected_.size() % kEntitiesPerPacketEstimate == 0
                                             ? kPacketOverhead + 8 : 0.0);
      if (estimate + cost > budget_bytes_) break;
      estimate += cost;
      selected_.push_back(c);
    }
    std::sort(selected_.begin(), selected_.end(),
              [](const Candidate& a, const Candidate& b) { return a.id < b.id; });
  } else {
    selected_.swap(candidates_);
  }

  BeginPayload();
  for (const Candidate& c : selected_) {
    if (!stream_->Add(StreamView(*c.entity), c.fields)) {
      Flush(now, connection, out, counters);
      BeginPayload();
      if (!stream_->Add(StreamView(*c.entity), c.fields)) continue;
    }
    View& v = views_[c.entity->slot];
    v.last_sent = now;
    double interval = IntervalOf(ClassOf(*c.entity, now));
    // Room-wide send schedule: the entity is due at the points of a grid of its interval,
    // with a phase of its own (from its id) but the same for every receiver, so the room's
    // receivers send it in the same ticks and reference the same versions (shared baseline
    // keys: one body encode serves them all). One send per grid point while ticks come
    // faster than the interval, so the long-run rate is exact; a receiver that sent late
    // (loss, budget) is back on the grid after one send.
    if (interval > 0 && std::isfinite(interval)) {
      const double phase =
          static_cast<double>((c.id * 2654435761u) >> 8) * (1.0 / (1u << 24)) * interval;
      v.next_due = phase + (std::floor((now + kEpsilon - phase) / interval) + 1.0) * interval;
    } else {
      v.next_due = now + interval;  // a rate of 0: never again on schedule
    }
  }
  Flush(now, connection, out, counters);
}

void ClientReplicator::Flush(double now, Connection& connection, PacketWriter& out,
                             RelayCounters& counters) {
  const size_t entities = stream_->count();
  const size_t size = stream_->Finish();
  if (size == 0) return;
  Result<uint16_t> seq = connection.SendUnreliable({payload_.data(), size}, now, out);
  if (seq.ok()) {
    stream_->OnSent(*seq, now);
    RelayCounters::Inc(counters.entity_updates_sent, entities);
  }
  StreamCounts counts;
  stream_->Count(seq.ok(), counts);
  if (counts.shared_bodies_cached != 0) {
    RelayCounters::Inc(counters.shared_bodies_cached, counts.shared_bodies_cached);
  }
  if (counts.shared_bodies_coded != 0) {
    RelayCounters::Inc(counters.shared_bodies_coded, counts.shared_bodies_coded);
  }
  budget_bytes_ -= static_cast<double>(size) + kPacketOverhead;
  if (entities > 0) {
    // Running estimate of one entity's encoded size, for budget decisions before encoding.
    double per_entity = static_cast<double>(size) / static_cast<double>(entities);
    bytes_per_entity_ = 0.8 * bytes_per_entity_ + 0.2 * per_entity;
  }
}

void ClientReplicator::BeginPayload() { stream_->Begin(payload_, time_ms_); }

}  // namespace edgephys
