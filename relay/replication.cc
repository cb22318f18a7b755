#include "relay/replication.h"

#include <algorithm>
#include <cmath>

#include "relay/entity.h"
#include "relay/lockstep.h"

namespace edgephys {
namespace {

constexpr uint32_t kFlagAvatar = 1u << 3;  // schema::EntityFlags::Avatar
constexpr uint32_t kFlagHand = 1u << 4;    // schema::EntityFlags::Hand
// Entities assumed per datagram when estimating a selection's size.
constexpr size_t kEntitiesPerPacketEstimate = 64;
// Format 12: a body whose state has not changed for this long is sent at rest (PhyS reports
// only bodies that moved, so its last velocity may be a sleeping body's leftover).
constexpr double kRestingVelocityAfterS = 0.1;
// key_sample_arrival_stamp: the largest shift applied (a stalled world's lag is not copied).
constexpr double kMaxStampLagS = 0.25;

double Weight(PriorityClass c) {
  switch (c) {
    case PriorityClass::kCritical: return 4.0;
    case PriorityClass::kNormal: return 1.0;
    case PriorityClass::kAmbient: return 0.75;
    case PriorityClass::kResting: return 0.5;
  }
  return 1.0;
}

float Distance(const Vec3f& a, const Vec3f& b) {
  float dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

float AngleDeg(const Quatf& a, const Quatf& b) {
  float dot = std::fabs(a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w);
  return 2.0f * std::acos(std::min(1.0f, dot)) * 57.29578f;
}

// Normalised lerp on the shorter arc: within a fraction of a degree of the receivers' slerp at
// the angles a key-sample segment spans.
Quatf Nlerp(const Quatf& a, const Quatf& b, float u) {
  const float sign = a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w < 0 ? -1.0f : 1.0f;
  Quatf q{a.x + (sign * b.x - a.x) * u, a.y + (sign * b.y - a.y) * u,
          a.z + (sign * b.z - a.z) * u, a.w + (sign * b.w - a.w) * u};
  const float n = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
  return n > 0 ? Quatf{q.x / n, q.y / n, q.z / n, q.w / n} : a;
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

std::string_view ReplicationModeName(ReplicationMode mode) {
  switch (mode) {
    case ReplicationMode::kFloat: return "float";
    case ReplicationMode::kEdgephys: return "edgephys";
    case ReplicationMode::kPhoton: return "photon";
    case ReplicationMode::kPaper: return "paper";
  }
  return "unknown";
}

bool ParseReplicationMode(std::string_view text, ReplicationMode* mode) {
  for (ReplicationMode m : {ReplicationMode::kFloat, ReplicationMode::kEdgephys,
                            ReplicationMode::kPhoton, ReplicationMode::kPaper}) {
    if (text == ReplicationModeName(m)) {
      *mode = m;
      return true;
    }
  }
  return false;
}

ClientReplicator::ClientReplicator(const ReplicationConfig& config)
    : config_(config), payload_(kMaxUnreliablePayload) {
  switch (config_.mode) {
    case ReplicationMode::kPhoton:
      encoder_ = std::make_unique<PhotonEmulationEncoder>();
      break;
    case ReplicationMode::kPaper: {
      auto paper = std::make_unique<PaperEmulationEncoder>();
      paper_ = paper.get();
      encoder_ = std::move(paper);
      break;
    }
    case ReplicationMode::kEdgephys: {
      auto params = MakeQuantizationParams(QuantizationOf(config_));
      if (params.ok() && UsesSharedEncoding(config_)) {
        SharedDeltaStreamOptions options;
        if (UsesLockstep(config_)) {  // every stream of a lockstep room (relay/lockstep.h)
          include_own_ = true;
          options.ack_delay_ticks = config_.lockstep_ack_ticks;
        }
        auto shared = std::make_unique<SharedDeltaStream>(*params, options);
        shared_ = shared.get();
        encoder_ = std::move(shared);
        break;
      }
      if (params.ok()) {
        DeltaEncoderOptions options;
        options.velocities = config_.velocities;
        options.previous_reference = UsesPreviousReference(config_);
        options.record_times = UsesRecordTimes(config_);
        auto delta = std::make_unique<DeltaEncoder>(*params, options);
        delta_ = delta.get();
        encoder_ = std::move(delta);
        break;
      }
      config_.mode = ReplicationMode::kFloat;  // invalid quantisation: fall back to exact floats
      [[fallthrough]];
    }
    case ReplicationMode::kFloat:
      encoder_ = std::make_unique<FloatStateEncoder>();
      break;
  }
  if (config_.mode == ReplicationMode::kEdgephys) {
    soft_ = std::make_unique<SoftDeltaSender>(
        SoftDeltaSenderConfig{config_.position_step_m, config_.position_threshold_m});
  }
  candidates_.reserve(256);
  in_payload_.reserve(kMaxUnreliablePayload / 8);
}

ClientReplicator::~ClientReplicator() {
  if (lockstep_) lockstep_->Unregister(this);
}

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

bool ClientReplicator::DeadReckoned(const Entity& e, PriorityClass c) const {
  return delta_ != nullptr && config_.velocities && e.physics == PhysicsRole::kSimulated &&
         c != PriorityClass::kCritical;
}

bool ClientReplicator::StampsStateTime() const {
  return delta_ != nullptr && !config_.velocities &&
         (config_.key_sample_threshold_m > 0 || config_.stamp_state_time);
}

bool ClientReplicator::KeySampled(const Entity& e, PriorityClass c) const {
  return StampsStateTime() && config_.key_sample_threshold_m > 0 &&
         e.physics == PhysicsRole::kSimulated && c == PriorityClass::kAmbient;
}

double ClientReplicator::IntervalFor(const Entity& e, PriorityClass c) const {
  if (DeadReckoned(e, c) && config_.extrapolation_max_hz > 0) {
    return 1.0 / config_.extrapolation_max_hz;
  }
  if (KeySampled(e, c)) return 0;  // checked every tick: a key sample goes when it is due
  return IntervalOf(c);
}

const EntityVelocity* ClientReplicator::VelocityOf(const Entity& e, double now) {
  if (!config_.velocities || e.physics != PhysicsRole::kSimulated ||
      now - e.changed_at > kRestingVelocityAfterS) {
    return nullptr;
  }
  velocity_.linear = e.linear_velocity;
  velocity_.angular = e.angular_velocity;
  return &velocity_;
}

bool ClientReplicator::HermiteDue(uint32_t id, const Entity& e, double now) {
  EntityState sent;
  EntityVelocity sent_velocity;
  uint32_t sent_ms = 0;
  if (!delta_->NewestSent(id, &sent, &sent_velocity, &sent_ms)) return true;
  const double h = static_cast<int32_t>(time_ms_ - sent_ms) / 1000.0;
  if (h <= 0) return false;
  if (h >= config_.hermite_max_interval_s) return true;
  const EntityVelocity* v = VelocityOf(e, now);
  const Vec3f v1 = v != nullptr ? DequantizeVelocity(QuantizeVelocity(*v)).linear : Vec3f{};
  const double thr2 = static_cast<double>(config_.extrapolation_position_threshold_m) *
                      config_.extrapolation_position_threshold_m;
  for (const Entity::RecentState& r : e.recent) {
    // Relay times as the wire has them (ms, wrapping): the sample's offset into the segment.
    const double into =
        static_cast<int32_t>(static_cast<uint32_t>(static_cast<uint64_t>(r.t * 1000.0)) - sent_ms) /
        1000.0;
    if (!(into > 0 && into < h)) continue;
    const Vec3f p = HermitePosition(sent.position, sent_velocity.linear, e.state.position, v1, h,
                                    into / h);
    const double dx = p.x - r.position.x, dy = p.y - r.position.y, dz = p.z - r.position.z;
    if (dx * dx + dy * dy + dz * dz > thr2) return true;
  }
  return false;
}

ClientReplicator::KeyDue ClientReplicator::KeySampleDue(uint32_t id, const Entity& e,
                                                      double sent_state_time, int* kink) {
  *kink = -1;
  EntityState sent;
  EntityVelocity unused;
  uint32_t sent_ms = 0;
  if (!delta_->NewestSent(id, &sent, &unused, &sent_ms)) return KeyDue::kMaxInterval;
  // The max interval on the relay's clock: a body that stopped (no newer state) still gets its
  // final pose within it.
  const double since = static_cast<int32_t>(time_ms_ - sent_ms) / 1000.0;
  if (since <= 0) return KeyDue::kNo;
  // With key_sample_check_hz, one check period early: the next check may come that much later.
  const double early = config_.key_sample_check_hz > 0 ? 1.0 / config_.key_sample_check_hz : 0.0;
  if (since >= config_.key_sample_max_interval_s - early) return KeyDue::kMaxInterval;
  // The line a receiver draws runs from the newest state sent, at the time it was stamped with
  // (sent_state_time), to the present state at the time it holds; PhyS's states in between are
  // checked at the times they hold too. (Stamping them with their arrival instead, a step's
  // uneven computation later, with several steps sometimes arriving at once, made straight
  // paths look kinked.)
  const double h = e.state_time - sent_state_time;
  if (h <= 0) return KeyDue::kNo;
  const double thr = config_.key_sample_threshold_m;
  const double rot_thr = config_.key_sample_rotation_deg;
  // At the kink: the state furthest beyond the thresholds (in multiples of them) is the one to
  // send; otherwise the first stray decides.
  const bool at_kink = config_.key_sample_at_kink && delta_->record_times();
  double worst = 1.0;
  for (size_t i = 0; i < e.recent.size(); ++i) {
    const Entity::RecentState& r = e.recent[i];
    const double into = r.t - sent_state_time;
    if (!(into > 0 && into < h)) continue;
    const float u = static_cast<float>(into / h);
    const Vec3f p{sent.position.x + (e.state.position.x - sent.position.x) * u,
                  sent.position.y + (e.state.position.y - sent.position.y) * u,
                  sent.position.z + (e.state.position.z - sent.position.z) * u};
    const double excess =
        std::max(Distance(p, r.position) / thr,
                 AngleDeg(Nlerp(sent.rotation, e.state.rotation, u), r.rotation) / rot_thr);
    if (excess <= 1.0) continue;
    if (!at_kink) return KeyDue::kStrayed;
    if (excess > worst) {
      worst = excess;
      *kink = static_cast<int>(i);
    }
  }
  return *kink >= 0 ? KeyDue::kStrayed : KeyDue::kNo;
}

DeltaEncoder::UpdateNeed ClientReplicator::VelocityNeed(uint32_t id, const Entity& e,
                                                        const View& v, PriorityClass cls,
                                                        double now, double resend_after,
                                                        RelayCounters& counters) {
  (void)v;  // its extras (key samples' sent_state_time) are by the entity's slot
  using Need = DeltaEncoder::UpdateNeed;
  if (!config_.velocities) {
    const Need need = delta_->Need(id, e.state, config_.position_threshold_m,
                                   config_.rotation_threshold_deg, now, resend_after);
    if (need != Need::kSend || !KeySampled(e, cls)) return need;
    const KeyDue due = KeySampleDue(id, e, view_extras_[e.slot].sent_state_time, &last_kink_);
    last_due_ = due;
    if (due == KeyDue::kStrayed) RelayCounters::Inc(counters.key_samples_strayed);
    if (due == KeyDue::kMaxInterval) RelayCounters::Inc(counters.key_samples_max_interval);
    if (due != KeyDue::kNo) return need;
    return Need::kExtrapolatedWithin;  // the line from the newest sent still holds (not sticky)
  }
  if (!DeadReckoned(e, cls)) {
    return delta_->NeedExtrapolated(id, e.state, config_.position_threshold_m,
                                    config_.rotation_threshold_deg, now, resend_after, time_ms_);
  }
  if (config_.hermite_max_interval_s > 0) {  // receivers interpolate: selective sync, then the curve
    const Need need = delta_->Need(id, e.state, config_.position_threshold_m,
                                   config_.rotation_threshold_deg, now, resend_after);
    if (need != Need::kSend || HermiteDue(id, e, now)) return need;
    return Need::kExtrapolatedWithin;  // not yet (not sticky)
  }
  return delta_->NeedExtrapolated(id, e.state, config_.extrapolation_position_threshold_m,
                                  config_.extrapolation_rotation_threshold_deg, now, resend_after,
                                  time_ms_);
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
  if (frame.lockstep != nullptr && include_own_ && shared_ != nullptr) {
    if (!lockstep_) {
      lockstep_ = frame.lockstep;
      member_ = std::make_unique<LockstepMember>();
      lockstep_->Register(this);
    }
    member_->ticked = true;
    member_->last_tick = lockstep_->tick();
    if (member_->in) return CopyCanonical(*lockstep_, self, now, connection, out, counters);
  }
  TickEntities(frame, self, now, resend_after, &connection, &out, counters);
}

void ClientReplicator::TickEntities(const ReplicationFrame& frame, uint32_t self, double now,
                                    double resend_after, Connection* connection,
                                    PacketWriter* out, RelayCounters& counters) {
  const bool budgeted = config_.bandwidth_budget_bytes_per_s > 0;
  key_check_tick_ = true;
  if (StampsStateTime() && config_.key_sample_check_hz > 0) {
    const double period = std::floor(now * config_.key_sample_check_hz);
    key_check_tick_ = period != key_check_period_;
    if (key_check_tick_) key_check_period_ = period;
  }

  candidates_.clear();
  const bool arrival_stamp =
      StampsStateTime() && config_.key_sample_threshold_m > 0 && config_.key_sample_arrival_stamp;
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
      if (shared_ != nullptr) shared_->Prefetch(ahead);
    }
    const Entity& e = *frame.by_id[i];
    const uint32_t id = e.id;
    if (e.owner == self && !include_own_) continue;
    View& v = ViewOf(e);
    if (now + kEpsilon < v.next_due || v.settled_version == e.version) continue;
    PriorityClass cls = ClassOf(e, now);
    if (!key_check_tick_ && KeySampled(e, cls)) continue;
    uint8_t fields = kFieldPosition | kFieldRotation;
    bool want = false;
    last_due_ = KeyDue::kNo;
    last_kink_ = -1;
    switch (config_.mode) {
      case ReplicationMode::kPhoton:
        want = true;  // fixed rate, changed or not
        break;
      case ReplicationMode::kPaper:
        if (const ViewExtra& x = view_extras_[e.slot]; x.ever_sent) {
          fields = 0;
          if (Distance(e.state.position, x.last_sent_state.position) > config_.position_threshold_m) {
            fields |= kFieldPosition;
          }
          if (AngleDeg(e.state.rotation, x.last_sent_state.rotation) > config_.rotation_threshold_deg) {
            fields |= kFieldRotation;
          }
        }
        want = fields != 0;
        break;
      case ReplicationMode::kFloat:
        want = tracker_.NeedsSend(id, e.version, now, resend_after);
        break;
      case ReplicationMode::kEdgephys: {
        const DeltaEncoder::UpdateNeed need =
            shared_ != nullptr
                ? (e.shared != nullptr
                       ? shared_->Need(id, *e.shared, e.state, config_.position_threshold_m,
                                       config_.rotation_threshold_deg, now, resend_after)
                       : DeltaEncoder::UpdateNeed::kSend)
                : VelocityNeed(id, e, v, cls, now, resend_after, counters);
        if (need == DeltaEncoder::UpdateNeed::kAckedWithin) v.settled_version = e.version;
        want = need == DeltaEncoder::UpdateNeed::kSend;
        break;
      }
    }
    if (!want) continue;
    double waiting = std::max(now - v.last_sent, IntervalFor(e, cls));
    candidates_.push_back({Weight(cls) * std::min(waiting, 60.0), id, &e, fields,
                           static_cast<uint8_t>(last_due_), static_cast<int8_t>(last_kink_)});
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

  // Key-sample rooms stamp PhyS bodies with the time their states hold (Entity::state_time),
  // in payloads of their own, so that a receiver's straight lines run through PhyS's states at
  // their times, as KeySampleDue checks them; everything else goes with the tick's time.
  const bool physics_stamped = StampsStateTime();
  auto to_ms = [](double t) { return static_cast<uint32_t>(static_cast<uint64_t>(t * 1000.0)); };
  uint32_t physics_ms = time_ms_;
  // key_sample_arrival_stamp: what the wire's times add to the times the states hold (ms): the
  // room's running mean of PhyS's lag, so that a receiver shows each state when the relay got
  // it, on average. A running mean moves slowly: a line's two ends are shifted alike.
  const uint32_t shift_ms = arrival_stamp && frame.physics_lag_s > 0
                                ? to_ms(std::min(frame.physics_lag_s, kMaxStampLagS) + 0.0005)
                                : 0;
  if (physics_stamped) {
    double newest = -1;
    for (const Candidate& c : selected_) {
      if (c.entity->physics == PhysicsRole::kSimulated) newest = std::max(newest, c.entity->state_time);
    }
    if (newest >= 0 && newest <= now) physics_ms = to_ms(newest);
  }
  for (int pass = physics_stamped ? 0 : 1; pass < 2; ++pass) {
    const uint32_t payload_ms = pass == 0 ? physics_ms + shift_ms : time_ms_;
    const uint32_t applied_shift_ms = pass == 0 ? payload_ms - physics_ms : 0;
    encoder_->Begin(payload_, payload_ms);
    in_payload_.clear();
    for (const Candidate& c : selected_) {
      if (physics_stamped && (pass == 0) != (c.entity->physics == PhysicsRole::kSimulated)) continue;
      auto add = [&]() {
        if (paper_ != nullptr) return paper_->AddFields(c.entity->state, c.fields);
        if (shared_ != nullptr) {  // the room codes the body once for every receiver
          return c.entity->shared != nullptr && c.entity->prepared_valid &&
                 shared_->Add(c.id, *c.entity->shared);
        }
        if (delta_ != nullptr && c.kink >= 0) {  // format 14: the kink, at its own time
          const Entity::RecentState& r = c.entity->recent[static_cast<size_t>(c.kink)];
          EntityState s = c.entity->state;
          s.position = r.position;
          s.rotation = r.rotation;
          return delta_->AddAt(s, nullptr, to_ms(r.t) + applied_shift_ms);
        }
        if (delta_ != nullptr) {  // the room quantised it once for every receiver
          return delta_->Add(c.entity->state,
                             c.entity->prepared_valid ? &c.entity->prepared : nullptr,
                             VelocityOf(*c.entity, now));
        }
        return encoder_->Add(c.entity->state);
      };
      if (!add()) {
        Flush(now, connection, out, counters);
        encoder_->Begin(payload_, payload_ms);
        if (!add()) continue;
      }
      if (shared_ == nullptr) in_payload_.emplace_back(c.id, c.entity->version);  // format 9: count()
      if (c.entity->owner == self) ++own_in_payload_;  // include_own_: not counted as delivered
      if (lockstep_capture_ != nullptr) payload_owners_.push_back(c.entity->owner);
      if (delta_ != nullptr) {  // counted here, added to the shared counters once a tick
        static_assert(kRecordPartCount == 6 && static_cast<int>(KeyDue::kMaxInterval) == 2);
        ++records_tick_[c.cause];
        for (size_t i = 0; i < kRecordPartCount; ++i) {
          record_bits_tick_[c.cause][i] += delta_->last_record_bits()[i];
        }
      }
      View& v = views_[c.entity->slot];
      v.last_sent = now;
      double interval = IntervalFor(*c.entity, ClassOf(*c.entity, now));
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
      if (!view_extras_.empty()) {
        ViewExtra& x = view_extras_[c.entity->slot];
        // The time the record holds, unshifted (KeySampleDue draws lines in state times).
        x.sent_state_time = c.kink >= 0 ? c.entity->recent[static_cast<size_t>(c.kink)].t
                                        : (payload_ms - applied_shift_ms) / 1000.0;
        if (c.fields & kFieldPosition) x.last_sent_state.position = c.entity->state.position;
        if (c.fields & kFieldRotation) x.last_sent_state.rotation = c.entity->state.rotation;
        x.ever_sent = true;
      }
    }
    Flush(now, connection, out, counters);
  }
  for (size_t c = 0; c < records_tick_.size(); ++c) {
    if (records_tick_[c] == 0) continue;
    RelayCounters::Inc(counters.state_records[c], records_tick_[c]);
    for (size_t i = 0; i < kRecordPartCount; ++i) {
      RelayCounters::Inc(counters.state_record_bits[c][i], record_bits_tick_[c][i]);
      record_bits_tick_[c][i] = 0;
    }
    records_tick_[c] = 0;
  }
}

void ClientReplicator::Flush(double now, Connection* connection, PacketWriter* out,
                             RelayCounters& counters) {
  // Format 9 keeps no per-entity list here (its stream records the sends): its count.
  const size_t entities = shared_ != nullptr ? shared_->count() : in_payload_.size();
  const size_t own = own_in_payload_;
  own_in_payload_ = 0;
  size_t size = encoder_->Finish();
  if (size == 0) {
    in_payload_.clear();
    payload_owners_.clear();
    return;
  }
  // A lockstep group's canonical replicator: the group keeps the payload for its receivers,
  // and the canonical stream counts it acknowledged (due after the group's ack ticks).
  Result<uint16_t> seq =
      lockstep_capture_ != nullptr
          ? Result<uint16_t>(lockstep_capture_->Capture({payload_.data(), size}, entities,
                                                        shared_->open_payload(), payload_owners_))
          : connection->SendUnreliable({payload_.data(), size}, now, *out);
  payload_owners_.clear();
  if (seq.ok()) {
    if (delta_ != nullptr) {
      delta_->OnSent(*seq, now);
    } else if (shared_ != nullptr) {
      shared_->OnSent(*seq, now);
      if (lockstep_capture_ != nullptr) shared_->OnPacketAcked(*seq);
    } else {
      for (const auto& [id, version] : in_payload_) tracker_.OnSent(*seq, id, version, now);
    }
    if (lockstep_capture_ == nullptr) {  // the canonical's are counted as its copies are sent
      RelayCounters::Inc(counters.entity_updates_sent, entities - own);
    }
    if (shared_ != nullptr) {
      const SharedDeltaStreamStats& st = shared_->stats();
      RelayCounters::Inc(counters.shared_bodies_cached, st.cache_hits - shared_hits_counted_);
      RelayCounters::Inc(counters.shared_bodies_coded, (st.entities - shared_entities_counted_) -
                                                           (st.cache_hits - shared_hits_counted_));
    }
  }
  if (shared_ != nullptr) {
    shared_hits_counted_ = shared_->stats().cache_hits;
    shared_entities_counted_ = shared_->stats().entities;
  }
  budget_bytes_ -= static_cast<double>(size) + kPacketOverhead;
  if (entities > 0) {
    // Running estimate of one entity's encoded size, for budget decisions before encoding.
    double per_entity = static_cast<double>(size) / static_cast<double>(entities);
    bytes_per_entity_ = 0.8 * bytes_per_entity_ + 0.2 * per_entity;
  }
  in_payload_.clear();
}

}  // namespace edgephys
