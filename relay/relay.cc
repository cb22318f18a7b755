// Relay: the loop (Update: datagrams, sessions, physics, room ticks), sessions and PhyS workers.
// Rooms, membership and operator actions are in relay_rooms.cc; the handshake and admission of new
// sessions in relay_handshake.cc.
#include "relay/relay.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <limits>

#include "protocol/byte_io.h"
#include "relay/cluster_hook.h"
#include "relay/drop_log.h"

namespace edgephys {
namespace {

using schema::RejectReason;

// The schema's name of a connection's DisconnectReason (same values), e.g. "Timeout".
const char* DisconnectReasonName(DisconnectReason reason) {
  const char* name =
      schema::EnumNameDisconnectReason(static_cast<schema::DisconnectReason>(reason));
  return name[0] != '\0' ? name : "unknown reason";
}

// Silence after which a PhyS worker counts as dead (its rooms fail over).
constexpr double kWorkerTimeoutS = 0.5;

DropLog& Log() { return DropLogOfThisThread(); }

}  // namespace

Relay::Relay(const RelayConfig& config, DatagramSocket* socket, RelayCounters* counters,
             const RelayShardOptions& shard)
    : config_(config),
      shard_(shard),
      physics_pool_(std::max<size_t>(1, config.physics_threads), config.physics_nice,
                    config.physics_idle),
      handshake_limiter_(config.limits.handshakes_per_s, config.limits.handshakes_per_s * 2),
      socket_(socket),
      counters_(counters),
      cookies_(shard.cookie_key ? CookieJar(*shard.cookie_key) : CookieJar()),
      workers_(config.physics),
      receive_buffer_(kMaxPacketSize + 512) {
  if (shard_.count == 0) shard_.count = 1;
  shard_.index %= shard_.count;
}

Relay::~Relay() {
  // Rooms before sessions (members are destroyed in reverse order, sessions_ first): a room's
  // remote PhyS link holds its worker Session and sends it WorkerUnassign when destroyed.
  for (const auto& [name, room] : rooms_) ForgetRoomWork(*room);
  rooms_.clear();
  for (const auto& [id, s] : sessions_) PublishHeld(*s, 0);  // the gauge is a sum of shares
  if (shard_.shared_counters) {  // withdraw this relay's share of the shared gauges
    PublishGauge(counters_->rooms, &published_rooms_, 0);
    PublishGauge(counters_->clients, &published_clients_, 0);
    PublishGauge(counters_->physics_bodies, &published_bodies_, 0);
    PublishGauge(counters_->physics_sleeping_bodies, &published_sleeping_, 0);
  }
}

void Relay::PublishGauge(RelayCounters::Gauge& gauge, int64_t* published, int64_t value) {
  if (!shard_.shared_counters) {
    gauge.store(value, std::memory_order_relaxed);
    return;
  }
  gauge.fetch_add(value - *published, std::memory_order_relaxed);
  *published = value;
}

void Relay::Update(double now, uint64_t unix_now_s) {
  now_ = now;
  if (cluster_) cluster_->Update(now, unix_now_s);
  // Datagrams of bulk rooms' members are set aside here and handled after the light rooms'
  // tick (HandleDeferredDatagrams, from TickDueRooms).
  deferring_ = true;
  deferred_.clear();
  deferred_bytes_.clear();
  for (size_t i = 0; i < config_.max_datagrams_per_update; ++i) {
    Endpoint from;
    size_t n = socket_->ReceiveFrom(&from, receive_buffer_);
    if (n == 0) break;
    RelayCounters::Inc(counters_->packets_received);
    RelayCounters::Inc(counters_->bytes_received, n);
    if (n > kMaxDatagramSize) {
      counters_->RejectPacket(DropReason::kTooLarge);
      Log().Note("datagram dropped", DropReasonName(DropReason::kTooLarge), from, now);
      continue;
    }
    HandleDatagram(from, std::span<const uint8_t>(receive_buffer_.data(), n), now, unix_now_s);
  }
  deferring_ = false;

  // PhyS steps before the rooms tick and the connections are serviced, so the reliable
  // events of this step (Grabbed, Enter/Exit) leave in this update: in the state datagrams of
  // the rooms that tick now (Connection::SendUnreliable carries the due reliable units and
  // the acks that fit), the rest in the connections' own packets right after: 28 % fewer
  // sealed datagrams at 100 users in a room.
  StepAllPhysics(now);
  const bool once_a_second = now - last_rtt_sample_ >= 1.0;
  if (once_a_second) last_rtt_sample_ = now;
  TickDueRooms(now);
  HandleDeferredDatagrams(now);  // none left: TickDueRooms handled them
  UpdateSessions(now, once_a_second);
  CloseIdleRooms(now);
  FlushSends();
  PublishGauges(once_a_second);
  room_work_.Publish(&counters_->room_work, now);
}

void Relay::ForgetRoomWork(const RoomHost& room) {
  room_work_.Forget(&room, room.name(), &counters_->room_work);
}

void Relay::HandleDeferredDatagrams(double now) {
  for (const DeferredDatagram& d : deferred_) {
    // The session may have gone since (replaced by a new Connect from its address, or an
    // older session of a player who joined again).
    auto it = sessions_.find(d.connection_id);
    if (it == sessions_.end()) {
      counters_->RejectPacket(DropReason::kUnknownConnection);
      continue;
    }
    Session& s = *it->second;
    if (s.endpoint() != d.from || !s.connection().connected()) continue;
    HandleSessionPacket(s, std::span<const uint8_t>(deferred_bytes_.data() + d.offset, d.size), now);
  }
  deferred_.clear();
  deferred_bytes_.clear();
}

void Relay::FlushSends() {
  // A batching socket sends what this update queued; datagrams the OS refused are lost.
  RelayCounters::Inc(counters_->send_errors, socket_->Flush());
}

void Relay::UpdateSessions(double now, bool sample_rtt) {
  removal_scratch_.clear();
  if (!sample_rtt && now < sessions_deadline_) {
    // No connection timer is due: only the sessions used since the last pass (Session::
    // ServiceSoon) need servicing. Those made due while these are serviced wait for the next.
    due_scratch_.swap(due_sessions_);
    due_sessions_.clear();
    double next = sessions_deadline_;
    for (uint32_t id : due_scratch_) {
      auto it = sessions_.find(id);
      if (it == sessions_.end() || now < it->second->service_at()) continue;  // gone, or serviced
      ServiceSession(id, *it->second, now, &next);
    }
    due_scratch_.clear();
    for (uint32_t id : removal_scratch_) RemoveSession(id, now);
    sessions_deadline_ = next;
    return;
  }
  due_sessions_.clear();  // the pass below services them; any made due during it wait
  double next = std::numeric_limits<double>::infinity();
  for (auto& [id, s] : sessions_) {
    if (sample_rtt && s->connection().stats().rtt_s > 0) {
      counters_->rtt_seconds.Observe(s->connection().stats().rtt_s);
    }
    // Only sessions with something due: a timer of their connection, or anything that used
    // the connection since (Session::ServiceSoon).
    if (now < s->service_at()) {
      next = std::min(next, s->service_at());
      continue;
    }
    ServiceSession(id, *s, now, &next);
  }
  for (uint32_t id : removal_scratch_) RemoveSession(id, now);
  // Sessions made due during the pass are in due_sessions_ and are serviced at the next one.
  sessions_deadline_ = next;
}

void Relay::ServiceSession(uint32_t id, Session& s, double now, double* next) {
  s.set_now(now);
  const auto work_start = RoomWorkLedger::Clock::now();
  uint64_t resends = s.connection().stats().reliable_resends;
  s.connection().Update(now, s);
  if (RoomHost* room = s.room(); room != nullptr) {
    room_work_.Charge(room, &room->name(), RoomWorkLedger::SecondsSince(work_start));
  }
  RelayCounters::Inc(counters_->reliable_resends, s.connection().stats().reliable_resends - resends);
  double at = s.connection().NextTimer();
  if (s.closing()) at = std::min(at, s.close_deadline());
  if (!s.is_worker() && !s.closing() && s.room() == nullptr && config_.limits.join_timeout_s > 0) {
    at = std::min(at, s.connected_at() + config_.limits.join_timeout_s);
  }
  s.set_service_at(at);
  *next = std::min(*next, at);
  if (s.CloseDue(now) && s.connection().connected()) {  // an operator's close
    s.connection().Disconnect(s.close_reason(), s);
  }
  if (!s.connection().connected()) {
    removal_scratch_.push_back(id);
  } else if (!s.is_worker() && !s.closing() && s.room() == nullptr && config_.limits.join_timeout_s > 0 &&
             now - s.connected_at() > config_.limits.join_timeout_s) {
    // A connection that holds a slot without ever joining a room (slow or idle handshake).
    Log().Note("connection dropped", "no room joined in time", s.endpoint(), now);
    s.connection().Disconnect(DisconnectReason::kKicked, s);
    removal_scratch_.push_back(id);
  }
}

void Relay::OnServiceSoon(Session& s) { due_sessions_.push_back(s.connection().id()); }

void Relay::PublishGauges(bool physics) {
  if (physics) {  // once a second: PhyS gauges
    int64_t bodies = 0, sleeping = 0;
    for (auto& [name, room] : rooms_) {
      if (room->room().physics() == nullptr) continue;
      physics::PhysicsCounters pc = room->room().physics()->counters();
      bodies += static_cast<int64_t>(pc.bodies);
      sleeping += static_cast<int64_t>(pc.sleeping_bodies);
    }
    PublishGauge(counters_->physics_bodies, &published_bodies_, bodies);
    PublishGauge(counters_->physics_sleeping_bodies, &published_sleeping_, sleeping);
  }
  PublishGauge(counters_->rooms, &published_rooms_, static_cast<int64_t>(rooms_.size()));
  PublishGauge(counters_->clients, &published_clients_, static_cast<int64_t>(sessions_.size()));
}

void Relay::HandleDatagram(const Endpoint& from, std::span<const uint8_t> data, double now,
                           uint64_t unix_now_s) {
  PacketPrefix prefix{};
  DropReason reason{};
  auto drop = [&](DropReason r) {
    counters_->RejectPacket(r);
    Log().Note("datagram dropped", DropReasonName(r), from, now);
  };
  // A sealed packet may be kSealOverhead longer than kMaxPacketSize; nothing else may.
  if (!ParsePacketPrefix(data.first(std::min(data.size(), kMaxPacketSize)), &prefix, &reason)) {
    return drop(reason);
  }
  const bool oversized = data.size() > kMaxPacketSize;
  switch (prefix.type) {
    case PacketType::kHello:
    case PacketType::kConnect:
      if (oversized) return drop(DropReason::kTooLarge);
      if (!handshake_limiter_.Allow(from, now)) return drop(DropReason::kRateLimited);
      if (prefix.type == PacketType::kHello) return HandleHello(from, data, now);
      return HandleConnect(from, data, now, unix_now_s);
    case PacketType::kData:
    case PacketType::kDisconnect: {
      auto it = sessions_.find(prefix.connection_id);
      if (it == sessions_.end()) return drop(DropReason::kUnknownConnection);
      Session& s = *it->second;
      if (s.endpoint() != from) return drop(DropReason::kWrongAddress);
      if (!s.connection().connected()) return;  // closing: redundant disconnect copies
      if (!s.AllowPacket(now, data.size())) return drop(DropReason::kRateLimited);
      if (deferring_ && s.room() != nullptr && IsBulk(*s.room())) {
        deferred_.push_back({from, prefix.connection_id, deferred_bytes_.size(), data.size()});
        deferred_bytes_.insert(deferred_bytes_.end(), data.begin(), data.end());
        RelayCounters::Inc(counters_->bulk_datagrams_deferred);
        return;
      }
      return HandleSessionPacket(s, data, now);
    }
    default:
      return drop(DropReason::kUnknownType);
  }
}

void Relay::HandleSessionPacket(Session& s, std::span<const uint8_t> data, double now) {
  const auto work_start = RoomWorkLedger::Clock::now();
  DropReason reason{};
  auto drop = [&](DropReason r) {
    counters_->RejectPacket(r);
    Log().Note("datagram dropped", DropReasonName(r), s.endpoint(), now);
  };
  auto charge = [&] {
    if (RoomHost* room = s.room(); room != nullptr) {
      room_work_.Charge(room, &room->name(), RoomWorkLedger::SecondsSince(work_start));
    }
  };
  std::span<const uint8_t> packet = data;
  if (s.sealed()) {
    // Forged (even with the victim's exact address and connection id), corrupted or
    // replayed: dropped and counted before the connection sees anything.
    packet = s.Open(data, &reason);
    if (packet.empty() && reason == DropReason::kReplayed) {
      // Also what a network duplicate is: ordinary, so counted but not logged.
      counters_->RejectPacket(reason);
      return charge();
    }
    if (packet.empty()) {
      drop(reason);
      return charge();
    }
  } else if (data.size() > kMaxPacketSize) {
    return drop(DropReason::kTooLarge);
  }
  s.set_now(now);
  s.ServiceSoon();
  Status st = s.connection().ProcessPacket(packet, now, s);
  if (st.code() == StatusCode::kAlreadyExists) {
    // The network delivered a packet twice: ordinary, so counted but not logged.
    counters_->RejectPacket(DropReason::kDuplicate);
  } else if (st.code() == StatusCode::kQueueFull) {
    drop(DropReason::kReassemblyFull);  // not acknowledged: an honest peer resends it
  } else if (!st.ok()) {
    drop(DropReason::kMalformed);
  }
  charge();
  AccountReassembly(s, now);
}

void Relay::PublishHeld(Session& s, size_t held) {
  const auto delta = static_cast<int64_t>(held) - static_cast<int64_t>(s.held_published());
  if (delta != 0) counters_->reassembly_held_bytes.fetch_add(delta, std::memory_order_relaxed);
  s.set_held_published(held);
}

void Relay::AccountReassembly(Session& s, double now) {
  const size_t held = s.connection().connected() ? s.connection().reliable_partial_bytes() : 0;
  const bool grew = held > s.held_published();
  PublishHeld(s, held);
  const size_t cap = config_.limits.max_reassembly_bytes;
  if (!grew || cap == 0) return;
  // Past the cap: end the largest holder of this relay, provided it holds more than an even
  // share of the cap (with shards, the relay holding the largest share of the excess acts; a
  // light holder is never the one to go because another shard's client is heavy).
  while (counters_->reassembly_held_bytes.load(std::memory_order_relaxed) >
         static_cast<int64_t>(cap)) {
    Session* largest = nullptr;
    for (auto& [id, other] : sessions_) {
      if (other->is_worker()) continue;  // PhyS workers are the operator's own
      if (largest == nullptr || other->held_published() > largest->held_published()) {
        largest = other.get();
      }
    }
    // The clients gauge is published once per update; this relay's own count is exact.
    const int64_t clients = std::max<int64_t>(
        {1, counters_->clients.load(std::memory_order_relaxed),
         static_cast<int64_t>(sessions_.size())});
    if (largest == nullptr || largest->held_published() == 0 ||
        static_cast<int64_t>(largest->held_published()) < static_cast<int64_t>(cap) / clients) {
      return;
    }
    Log().Note("connection dropped", "reassembly memory cap", largest->endpoint(), now);
    RelayCounters::Inc(counters_->reassembly_evictions);
    largest->connection().Disconnect(DisconnectReason::kKicked, *largest);
    largest->ServiceSoon();  // removed (and its memory freed) by this update's UpdateSessions
    sessions_deadline_ = -std::numeric_limits<double>::infinity();
    PublishHeld(*largest, 0);
  }
}

void Relay::Transmit(const Endpoint& to, std::span<const uint8_t> data) {
  Status st = socket_->SendTo(to, data);
  if (!st.ok()) {
    RelayCounters::Inc(counters_->send_errors);
    return;
  }
  RelayCounters::Inc(counters_->packets_sent);
  RelayCounters::Inc(counters_->bytes_sent, data.size());
}

void Relay::OnWorkerHello(Session& s) {
  if ((s.permissions() & kPermissionWorker) == 0) {
    return s.SendError(RejectReason::NotOwner, 0, "the token is not a worker token");
  }
  if (s.is_worker()) return;
  s.set_worker(true);
  s.connection().SetTimeout(kWorkerTimeoutS);
  workers_.Attach(s.connection().id(), &s);
  counters_->physics_workers.fetch_add(1, std::memory_order_relaxed);
  spdlog::info("PhyS worker {:08x} attached from {}:{}", s.connection().id(),
               s.endpoint().address().to_string(), s.endpoint().port());
}

void Relay::OnWorkerResult(Session& s, const schema::WorkerResult& result) {
  if (s.is_worker()) (void)workers_.RouteResult(s.connection().id(), result, now_);
}

void Relay::OnWorkerStates(Session& s, std::span<const uint8_t> payload) {
  (void)workers_.RouteStates(s.connection().id(), payload, now_);
}

void Relay::StepAllPhysics(double now) {
  physics_rooms_.clear();
  physics_links_.clear();
  // Embedded PhyS runs on the pool's physics threads (physics_threads > 1): Advance() below
  // hands `now` over and picks up the steps finished meanwhile, never waiting for one. With
  // physics_threads == 1 (null) the worlds step here, synchronously, as they always did.
  AsyncPhysicsPool* async = nullptr;
  for (auto& [name, room] : rooms_) {
    const auto work_start = RoomWorkLedger::Clock::now();
    PhysicsLink* link = room->PreparePhysics(now);
    room_work_.Charge(room.get(), &room->name(), RoomWorkLedger::SecondsSince(work_start));
    if (link == nullptr) continue;
    if (async == nullptr) async = physics_pool_.async_physics();
    if (async != nullptr) link->RunOn(async);  // new or failed-over links: from now on
    physics_rooms_.push_back(room.get());
    physics_links_.push_back(link);
  }
  double slowest = std::numeric_limits<double>::quiet_NaN();
  if (!physics_rooms_.empty()) {
    if (step_outputs_.size() < physics_rooms_.size()) step_outputs_.resize(physics_rooms_.size());
    // Asynchronous and remote links return at once; synchronous ones step here.
    for (size_t i = 0; i < physics_links_.size(); ++i) {
      const auto work_start = RoomWorkLedger::Clock::now();
      physics_links_[i]->Advance(now, &step_outputs_[i]);
      room_work_.Charge(physics_rooms_[i], &physics_rooms_[i]->name(),
                        RoomWorkLedger::SecondsSince(work_start));
    }
    for (size_t i = 0; i < physics_rooms_.size(); ++i) {
      const auto work_start = RoomWorkLedger::Clock::now();
      physics_rooms_[i]->ApplyPhysics(step_outputs_[i], now);
      room_work_.Charge(physics_rooms_[i], &physics_rooms_[i]->name(),
                        RoomWorkLedger::SecondsSince(work_start));
      slowest = std::fmin(slowest, physics_links_[i]->realtime_factor());  // NaN: unknown
    }
  }
  counters_->PublishRealtimeFactor(shard_.index, slowest);
}

void Relay::TickDueRooms(double now) {
  // Every due room's receivers are independent: each replicator reads its room's entities
  // (unchanged during the tick) and writes only its own session. They run on the pool; their
  // datagrams are queued per session and sent from this thread afterwards.
  // Two passes: rooms of at most kBulkRoomEntities entities (as of their last tick) first, their
  // datagrams sent, then the bulk rooms (a PhyS scene of thousands of bodies). A bulk room's
  // frame, picks and encoding then never delay another room's hand poses within an update.
  auto start = std::chrono::steady_clock::now();
  size_t due_rooms = 0;
  bulk_rooms_.clear();
  for (int pass = 0; pass < 2; ++pass) {
    // Between the passes: the bulk rooms' members' datagrams set aside by Update's receive
    // loop (their acks then count in the bulk rooms' tick below).
    if (pass == 1) HandleDeferredDatagrams(now);
    const auto pass_start = std::chrono::steady_clock::now();
    tick_jobs_.clear();
    auto add = [&](RoomHost& room) {
      ++due_rooms;
      const auto work_start = RoomWorkLedger::Clock::now();
      receivers_.clear();
      room.BeginTick(now, &receivers_);
      for (MemberLink* m : receivers_) tick_jobs_.push_back({&room.room().frame(), m, &room, 0.0});
      room_work_.Charge(&room, &room.name(), RoomWorkLedger::SecondsSince(work_start));
    };
    if (pass == 0) {
      for (auto& [name, room] : rooms_) {
        if (!room->TickDue(now)) continue;
        if (room->room().frame().by_id.size() > kBulkRoomEntities) {
          bulk_rooms_.push_back(room.get());
        } else {
          add(*room);
        }
      }
    } else {
      // A due bulk room waits for a light room due within the bulk pass's duration
      // (BulkTickScheduler), then ticks right after it.
      double next_light = std::numeric_limits<double>::infinity();
      if (!bulk_rooms_.empty()) {
        for (const auto& [name, room] : rooms_) {
          if (!IsBulk(*room)) next_light = std::min(next_light, room->room().next_tick());
        }
      }
      bulk_hold_until_ = -std::numeric_limits<double>::infinity();
      for (RoomHost* room : bulk_rooms_) {
        const double interval = 1.0 / std::max(1.0, room->room().config().tick_rate_hz);
        if (bulk_scheduler_.ShouldWait(now, room->room().next_tick(), interval, next_light)) {
          bulk_hold_until_ = next_light;
          continue;
        }
        add(*room);
      }
    }
    if (tick_jobs_.empty()) continue;
    // Serial: send as we go. Parallel: queue per session, send after the join.
    const bool parallel = physics_pool_.threads() > 1 && tick_jobs_.size() > 1;
    physics_pool_.Run(tick_jobs_.size(), [this, now, parallel](size_t i) {
      const auto work_start = RoomWorkLedger::Clock::now();
      tick_jobs_[i].member->Replicate(*tick_jobs_[i].frame, now, *counters_, parallel);
      tick_jobs_[i].seconds = RoomWorkLedger::SecondsSince(work_start);
    });
    // Each room's receivers are consecutive jobs: one charge per room.
    RoomHost* charged = nullptr;
    double seconds = 0;
    for (const TickJob& job : tick_jobs_) {
      const auto work_start = RoomWorkLedger::Clock::now();
      job.member->FlushReplication();
      if (job.room != charged && charged != nullptr) {
        room_work_.Charge(charged, &charged->name(), seconds);
        seconds = 0;
      }
      charged = job.room;
      seconds += job.seconds + RoomWorkLedger::SecondsSince(work_start);
    }
    if (charged != nullptr) room_work_.Charge(charged, &charged->name(), seconds);
    if (pass == 1) {
      bulk_scheduler_.RecordPass(
          std::chrono::duration<double>(std::chrono::steady_clock::now() - pass_start).count());
    }
  }
  if (due_rooms == 0) return;
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  counters_->tick_seconds.Observe(seconds / static_cast<double>(due_rooms));
}

void Relay::RemoveSession(uint32_t connection_id, double now) {
  auto it = sessions_.find(connection_id);
  if (it == sessions_.end()) return;
  Session& s = *it->second;
  if (s.room() != nullptr) OnLeaveRoom(s, now);
  if (s.is_worker()) {
    counters_->physics_workers.fetch_sub(1, std::memory_order_relaxed);
    spdlog::warn("PhyS worker {:08x} lost ({})", connection_id,
                 DisconnectReasonName(s.connection().disconnect_reason()));
    workers_.Detach(connection_id);
    for (auto& [name, room] : rooms_) {
      if (room->physics_worker() == connection_id) room->FailOver(now);
    }
  }
  PublishHeld(s, 0);
  DisconnectReason reason = s.connection().disconnect_reason();
  counters_->CountDisconnect(reason);
  spdlog::info("player {} disconnected ({})", s.player_id(), DisconnectReasonName(reason));
  auto eit = session_by_endpoint_.find(s.endpoint());
  if (eit != session_by_endpoint_.end() && eit->second == connection_id) {
    session_by_endpoint_.erase(eit);
  }
  sessions_.erase(it);
}

Status Relay::EnableCluster(const ClusterOptions& options) {
  if (shard_.count > 1) return Status::InvalidArgument("clusters need a single-shard relay");
  auto hook = ClusterHook::Start(this, options);
  if (!hook.ok()) return hook.status();
  cluster_ = std::move(*hook);
  return Status::Ok();
}

void Relay::Shutdown() {
  for (auto& [id, s] : sessions_) s->connection().Disconnect(DisconnectReason::kServerShutdown, *s);
  while (!sessions_.empty()) RemoveSession(sessions_.begin()->first, now_);
  FlushSends();
  if (shard_.shared_counters) PublishGauge(counters_->clients, &published_clients_, 0);
}

}  // namespace edgephys
