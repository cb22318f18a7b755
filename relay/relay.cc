#include "relay/relay.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>

#include "protocol/byte_io.h"
#include "relay/session.h"

namespace edgephys {
namespace {

using schema::RejectReason;

uint16_t Code(RejectReason r) { return static_cast<uint16_t>(r); }

// Whether clients want collision events of `e` (ReportContacts or Hand).
bool ReportsContacts(const Entity* e) {
  constexpr uint32_t kMask = static_cast<uint32_t>(schema::EntityFlags::ReportContacts) |
                             static_cast<uint32_t>(schema::EntityFlags::Hand);
  return e != nullptr && (e->flags & kMask) != 0;
}

// States held per session for entities whose spawn has not arrived yet.
constexpr size_t kMaxEarlyStates = 1024;
// Silence after which a PhyS worker counts as dead (its rooms fail over).
constexpr double kWorkerTimeoutS = 0.5;

// At most one log line per reason per second, with the number suppressed since.
class DropLog {
 public:
  void Note(std::string_view what, std::string_view reason, const Endpoint& from, double now) {
    Entry& e = entries_[std::string(reason)];
    ++e.suppressed;
    if (now - e.last >= 1.0) {
      spdlog::warn("{} from {}:{}: {} ({} since last report)", what, from.address().to_string(),
                   from.port(), reason, e.suppressed);
      e.last = now;
      e.suppressed = 0;
    }
  }

 private:
  struct Entry {
    double last = -1e9;
    uint64_t suppressed = 0;
  };
  std::map<std::string, Entry, std::less<>> entries_;
};

DropLog& Log() {
  static thread_local DropLog log;
  return log;
}

}  // namespace

Relay::Relay(const RelayConfig& config, DatagramSocket* socket, RelayCounters* counters,
             const RelayShardOptions& shard)
    : config_(config),
      shard_(shard),
      physics_pool_(std::max<size_t>(1, config.physics_threads)),
      handshake_limiter_(config.limits.handshakes_per_s, config.limits.handshakes_per_s * 2),
      socket_(socket),
      counters_(counters),
      cookies_(shard.cookie_key ? CookieJar(*shard.cookie_key) : CookieJar()),
      receive_buffer_(kMaxPacketSize + 512) {
  if (shard_.count == 0) shard_.count = 1;
  shard_.index %= shard_.count;
  batch_.states.reserve(kMaxPacketSize / 8);
}

Relay::~Relay() {
  // Rooms before sessions (members are destroyed in reverse order, sessions_ first): a room's
  // remote PhyS link holds its worker Session and sends it WorkerUnassign when destroyed.
  rooms_.clear();
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
  for (size_t i = 0; i < config_.max_datagrams_per_update; ++i) {
    Endpoint from;
    size_t n = socket_->ReceiveFrom(&from, receive_buffer_);
    if (n == 0) break;
    RelayCounters::Inc(counters_->packets_received);
    RelayCounters::Inc(counters_->bytes_received, n);
    if (n > kMaxPacketSize) {
      counters_->RejectPacket(DropReason::kTooLarge);
      Log().Note("datagram dropped", DropReasonName(DropReason::kTooLarge), from, now);
      continue;
    }
    HandleDatagram(from, std::span<const uint8_t>(receive_buffer_.data(), n), now, unix_now_s);
  }

  // PhyS steps before the connections are serviced, so the reliable events of this step
  // (Grabbed, Enter/Exit) leave in this update instead of waiting behind the replication
  // tick below, which at 100 users in a room takes most of a tick interval.
  StepAllPhysics(now);

  bool sample_rtt = now - last_rtt_sample_ >= 1.0;
  if (sample_rtt) last_rtt_sample_ = now;
  removal_scratch_.clear();
  for (auto& [id, s] : sessions_) {
    s->set_now(now);
    uint64_t resends = s->connection().stats().reliable_resends;
    s->connection().Update(now, *s);
    RelayCounters::Inc(counters_->reliable_resends,
                       s->connection().stats().reliable_resends - resends);
    if (sample_rtt && s->connection().stats().rtt_s > 0) {
      counters_->rtt_seconds.Observe(s->connection().stats().rtt_s);
    }
    if (!s->connection().connected()) {
      removal_scratch_.push_back(id);
    } else if (!s->is_worker() && s->room().empty() && config_.limits.join_timeout_s > 0 &&
               now - s->connected_at() > config_.limits.join_timeout_s) {
      // A connection that holds a slot without ever joining a room (slow or idle handshake).
      Log().Note("connection dropped", "no room joined in time", s->endpoint(), now);
      s->connection().Disconnect(DisconnectReason::kKicked, *s);
      removal_scratch_.push_back(id);
    }
  }
  for (uint32_t id : removal_scratch_) RemoveSession(id, now);

  TickDueRooms(now);
  CloseIdleRooms(now);
  if (sample_rtt) {  // once a second: PhyS gauges
    int64_t bodies = 0, sleeping = 0;
    for (auto& [name, room] : rooms_) {
      if (room->physics() == nullptr) continue;
      physics::PhysicsCounters pc = room->physics()->counters();
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
  if (!ParsePacketPrefix(data, &prefix, &reason)) return drop(reason);
  switch (prefix.type) {
    case PacketType::kHello:
    case PacketType::kConnect:
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
      s.set_now(now);
      Status st = s.connection().ProcessPacket(data, now, s);
      if (st.code() == StatusCode::kAlreadyExists) {
        // The network delivered a packet twice: ordinary, so counted but not logged.
        counters_->RejectPacket(DropReason::kDuplicate);
      } else if (!st.ok()) {
        drop(DropReason::kMalformed);
      }
      return;
    }
    default:
      return drop(DropReason::kUnknownType);
  }
}

void Relay::HandleHello(const Endpoint& from, std::span<const uint8_t> data, double now) {
  if (data.size() < kMinHelloPacketSize) {
    counters_->RejectPacket(DropReason::kHelloTooSmall);
    Log().Note("hello dropped", DropReasonName(DropReason::kHelloTooSmall), from, now);
    return;
  }
  const auto* msg = VerifyControlMessage(data.subspan(kPacketPrefixSize), schema::Body::Hello);
  if (msg == nullptr) {
    counters_->RejectPacket(DropReason::kMalformed);
    return;
  }
  auto cookie = cookies_.Issue(from, msg->body_as_Hello()->client_nonce(), now);
  flatbuffers::FlatBufferBuilder fbb(128);
  FinishControl(fbb, schema::CreateChallenge(fbb, fbb.CreateVector(cookie.data(), cookie.size())));
  auto packet = BuildHandshakePacket(PacketType::kChallenge, fbb);
  SendUnverified(from, packet, data.size());
}

void Relay::HandleConnect(const Endpoint& from, std::span<const uint8_t> data, double now,
                          uint64_t unix_now_s) {
  const auto* msg = VerifyControlMessage(data.subspan(kPacketPrefixSize), schema::Body::Connect);
  if (msg == nullptr) {
    counters_->RejectPacket(DropReason::kMalformed);
    return;
  }
  const auto* connect = msg->body_as_Connect();
  const auto* cookie = connect->cookie();
  if (cookie == nullptr ||
      !cookies_.Verify(std::span<const uint8_t>(cookie->data(), cookie->size()), from,
                       connect->client_nonce(), now)) {
    // The address is unverified: no answer at all.
    counters_->RejectPacket(DropReason::kBadCookie);
    Log().Note("connect dropped", DropReasonName(DropReason::kBadCookie), from, now);
    return;
  }
  std::span<const uint8_t> token_bytes;
  if (connect->token() != nullptr) {
    token_bytes = std::span<const uint8_t>(connect->token()->data(), connect->token()->size());
  }
  TokenError token_error;
  Result<JoinToken> token = VerifyJoinToken(token_bytes, config_.secret, unix_now_s, &token_error);
  if (!token.ok()) {
    RejectReason r = token_error == TokenError::kExpired ? RejectReason::ExpiredToken
                                                         : RejectReason::BadToken;
    Log().Note("connect rejected", schema::EnumNameRejectReason(r), from, now);
    return SendReject(from, Code(r), data.size());
  }

  // The same client repeating its Connect because our Accept was lost: repeat the Accept.
  if (auto it = session_by_endpoint_.find(from); it != session_by_endpoint_.end()) {
    Session& existing = *sessions_.at(it->second);
    if (existing.token_nonce() == token->nonce) {
      Send(from, existing.accept_packet());
      return;
    }
    // A new token from the same address: the client restarted. Replace the old session.
    existing.connection().Disconnect(DisconnectReason::kKicked, existing);
    RemoveSession(it->second, now);
  }
  if (sessions_.size() >= config_.max_clients) {
    return SendReject(from, Code(RejectReason::ServerFull), data.size());
  }
  if (config_.limits.max_sessions_per_address > 0) {
    size_t same_address = 0;
    for (const auto& [id, other] : sessions_) same_address += other->endpoint().address() == from.address();
    if (same_address >= config_.limits.max_sessions_per_address) {
      Log().Note("connect rejected", "too many connections from one address", from, now);
      return SendReject(from, Code(RejectReason::RateLimited), data.size());
    }
  }
  Status admitted = replay_guard_.Admit(token->nonce, token->expiry_unix_s, unix_now_s);
  if (!admitted.ok()) {
    RejectReason r = admitted.code() == StatusCode::kAlreadyExists ? RejectReason::ReplayedToken
                                                                   : RejectReason::ServerFull;
    Log().Note("connect rejected", schema::EnumNameRejectReason(r), from, now);
    return SendReject(from, Code(r), data.size());
  }

  uint32_t connection_id = 0;
  while (connection_id == 0 || sessions_.count(connection_id) != 0) {
    connection_id = static_cast<uint32_t>(SecureRandom64());
    if (shard_.count > 1) {  // the id's residue names this shard (0 if it would overflow)
      uint64_t id = connection_id - connection_id % shard_.count + uint64_t{shard_.index};
      connection_id = id > UINT32_MAX ? 0 : static_cast<uint32_t>(id);
    }
  }
  auto session = std::make_unique<Session>(this, from, connection_id, token->player_id,
                                           token->permissions, token->room, token->nonce,
                                           config_.connection, config_.limits, now);
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateAccept(
                         fbb, connection_id, token->player_id,
                         static_cast<uint32_t>(config_.connection.keepalive_interval_s * 1000),
                         static_cast<uint32_t>(config_.connection.timeout_s * 1000)));
  session->accept_packet() = BuildHandshakePacket(PacketType::kAccept, fbb);
  Send(from, session->accept_packet());
  session_by_endpoint_[from] = connection_id;
  sessions_[connection_id] = std::move(session);
  RelayCounters::Inc(counters_->connections_accepted);
  spdlog::info("player {} connected from {}:{} (connection {:08x})", token->player_id,
               from.address().to_string(), from.port(), connection_id);
}

void Relay::SendReject(const Endpoint& to, uint16_t reason, size_t request_size) {
  counters_->RejectRequest(reason);
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateReject(fbb, static_cast<RejectReason>(reason)));
  auto packet = BuildHandshakePacket(PacketType::kReject, fbb);
  SendUnverified(to, packet, request_size);
}

void Relay::SendUnverified(const Endpoint& to, std::span<const uint8_t> reply,
                           size_t request_size) {
  if (reply.size() > request_size) {
    // Never amplify towards an address that has not proven it owns itself.
    counters_->RejectPacket(DropReason::kHelloTooSmall);
    return;
  }
  Send(to, reply);
}

void Relay::Send(const Endpoint& to, std::span<const uint8_t> data) {
  Status st = socket_->SendTo(to, data);
  if (!st.ok()) {
    RelayCounters::Inc(counters_->send_errors);
    return;
  }
  RelayCounters::Inc(counters_->packets_sent);
  RelayCounters::Inc(counters_->bytes_sent, data.size());
}

Room* Relay::GetOrCreateRoom(const std::string& name, double now) {
  auto it = rooms_.find(name);
  if (it != rooms_.end()) return it->second.get();
  auto room = std::make_unique<Room>(name, config_.room_defaults, now);
  Room* r = room.get();
  rooms_[name] = std::move(room);
  spdlog::info("room '{}' created", name);
  return r;
}

Status Relay::CreateRoom(const std::string& name, const RoomConfig& config, double now) {
  if (name.empty() || name.size() > kMaxRoomNameSize) {
    return Status(StatusCode::kInvalidArgument, "room name must be 1..64 bytes");
  }
  if (config.capacity == 0 || config.capacity >= kEntityIdBlock || config.tick_rate_hz <= 0 ||
      config.tick_rate_hz > 1000) {
    return Status(StatusCode::kInvalidArgument, "room capacity or tick rate out of range");
  }
  auto it = rooms_.find(name);
  if (it != rooms_.end()) {
    if (!it->second->empty() || !it->second->entities().empty()) {
      return Status(StatusCode::kAlreadyExists, "room is in use");
    }
    rooms_.erase(it);
  }
  rooms_[name] = std::make_unique<Room>(name, config, now);
  return Status::Ok();
}

void Relay::SendError(Session& s, uint16_t reason, uint32_t entity_id, std::string_view detail) {
  counters_->RejectRequest(reason);
  Log().Note("request rejected", schema::EnumNameRejectReason(static_cast<RejectReason>(reason)),
             s.endpoint(), now_);
  flatbuffers::FlatBufferBuilder fbb(128);
  FinishControl(fbb, schema::CreateError(fbb, static_cast<RejectReason>(reason), entity_id,
                                         fbb.CreateString(detail.data(), detail.size())));
  if (!s.connection().SendReliable({fbb.GetBufferPointer(), fbb.GetSize()}).ok()) {
    s.connection().Disconnect(DisconnectReason::kReliableOverflow, s);
  }
}

void Relay::OnJoinRoom(Session& s, std::string_view room_name, double now) {
  std::string name(room_name);
  if (s.room() == name) return;  // already there
  if (name.empty() || name != s.token_room()) {
    return SendError(s, Code(RejectReason::WrongRoom), 0, "the join token does not grant this room");
  }
  if (!s.room().empty()) OnLeaveRoom(s, now);
  Room* room = GetOrCreateRoom(name, now);
  // The same player connected twice (e.g. a new device): the newer session wins.
  if (Member* old = room->FindMember(s.player_id())) {
    uint32_t old_session = old->session;
    auto it = sessions_.find(old_session);
    if (it != sessions_.end() && it->second.get() != &s) {
      it->second->connection().Disconnect(DisconnectReason::kKicked, *it->second);
      RemoveSession(old_session, now);
    }
  }
  uint32_t slot = room->AddMember(s.player_id(), s.connection().id());
  if (slot == 0) return SendError(s, Code(RejectReason::RoomFull), 0, "room is full");
  s.set_room(name);
  s.ResetReplicator(room->config().replication);
  s.early_states().clear();

  auto send = [&s](flatbuffers::FlatBufferBuilder& fbb) {
    if (!s.connection().SendReliable({fbb.GetBufferPointer(), fbb.GetSize()}).ok()) {
      s.connection().Disconnect(DisconnectReason::kReliableOverflow, s);
    }
  };
  flatbuffers::FlatBufferBuilder fbb(256);
  {
    const ReplicationConfig& rc = room->config().replication;
    const QuantizationConfig q = QuantizationOf(rc);
    uint8_t format = 1;
    switch (rc.mode) {
      case ReplicationMode::kEdgephys: format = kDeltaStateFormat; break;
      case ReplicationMode::kPhoton: format = kFormatPhoton; break;
      case ReplicationMode::kPaper: format = kFormatPaper; break;
      case ReplicationMode::kFloat: format = 1; break;
    }
    schema::Vec3 bmin(q.bounds_min.x, q.bounds_min.y, q.bounds_min.z);
    schema::Vec3 bmax(q.bounds_max.x, q.bounds_max.y, q.bounds_max.z);
    auto name_offset = fbb.CreateString(name);
    schema::JoinedBuilder jb(fbb);
    jb.add_room(name_offset);
    jb.add_player_id(s.player_id());
    jb.add_entity_id_base(slot * kEntityIdBlock);
    jb.add_tick_rate_hz(static_cast<uint16_t>(room->config().tick_rate_hz));
    jb.add_state_format(format);
    jb.add_position_step_m(q.position_step_m);
    jb.add_rotation_bound_deg(q.rotation_error_deg);
    jb.add_bounds_min(&bmin);
    jb.add_bounds_max(&bmax);
    FinishControl(fbb, jb.Finish());
  }
  send(fbb);
  s.HoldStatesUntilReliable(s.connection().reliable_queued_end());
  std::vector<uint32_t> players;
  for (const auto& [id, m] : room->members()) players.push_back(id);
  fbb.Clear();
  FinishControl(fbb, schema::CreateRoomState(fbb, fbb.CreateString(name), fbb.CreateVector(players),
                                             static_cast<uint32_t>(room->entities().size())));
  send(fbb);
  for (const auto& [id, e] : room->entities()) {
    if (!s.connection().SendReliable(e.spawn).ok()) {
      s.connection().Disconnect(DisconnectReason::kReliableOverflow, s);
      break;
    }
  }
  fbb.Clear();
  FinishControl(fbb, schema::CreatePlayerJoined(fbb, s.player_id()));
  BroadcastReliable(*room, {fbb.GetBufferPointer(), fbb.GetSize()}, s.player_id());
  spdlog::info("player {} joined room '{}' (slot {}, {} players)", s.player_id(), name, slot,
               room->size());
}

void Relay::OnLeaveRoom(Session& s, double now) {
  auto it = rooms_.find(s.room());
  s.set_room("");
  if (it == rooms_.end()) return;
  Room& room = *it->second;
  if (room.FindMember(s.player_id()) == nullptr ||
      room.FindMember(s.player_id())->session != s.connection().id()) {
    return;
  }
  std::vector<uint32_t> despawned;
  room.RemoveMember(s.player_id(), &despawned);
  counters_->entities.fetch_sub(static_cast<int64_t>(despawned.size()), std::memory_order_relaxed);
  // As in OnDespawn: the members who stay drop what they held of the despawned entities
  // (views, encoder baselines), or it would pile up for as long as they stay, and a later
  // entity reusing an id would be delta-coded against a baseline their client has dropped.
  for (const auto& [pid, m] : room.members()) {
    auto sit = sessions_.find(m.session);
    if (sit == sessions_.end()) continue;
    for (uint32_t id : despawned) sit->second->replicator().Forget(id);
  }
  flatbuffers::FlatBufferBuilder fbb(64);
  for (uint32_t id : despawned) {
    fbb.Clear();
    FinishControl(fbb, schema::CreateDespawn(fbb, id));
    BroadcastReliable(room, {fbb.GetBufferPointer(), fbb.GetSize()}, 0);
  }
  // Entities the room took over: their stored spawn now names the room as owner.
  for (const auto& [id, e] : room.entities()) {
    if (e.owner != 0) continue;
    auto* msg = schema::GetMutableControlMessage(const_cast<uint8_t*>(e.spawn.data()));
    auto* spawn = static_cast<schema::Spawn*>(msg->mutable_body());
    if (spawn->mutable_container() != nullptr) spawn->mutable_container()->mutate_owner(0);
  }
  fbb.Clear();
  FinishControl(fbb, schema::CreatePlayerLeft(fbb, s.player_id()));
  BroadcastReliable(room, {fbb.GetBufferPointer(), fbb.GetSize()}, 0);
  if (room.empty()) room.set_empty_since(now);
  spdlog::info("player {} left room '{}'", s.player_id(), room.name());
}

void Relay::OnSpawn(Session& s, std::span<const uint8_t> message, const schema::Spawn* spawn) {
  auto it = rooms_.find(s.room());
  if (it == rooms_.end()) return SendError(s, Code(RejectReason::NotJoined), 0, "join a room first");
  Room& room = *it->second;
  const schema::Container* c = spawn->container();
  if (c == nullptr || c->transform() == nullptr) {
    return SendError(s, Code(RejectReason::InvalidMessage), 0, "spawn without container/transform");
  }
  uint32_t id = c->entity_id();
  if (message.size() > config_.limits.max_spawn_bytes) {
    return SendError(s, Code(RejectReason::InvalidContainer), id, "container larger than the relay allows");
  }
  if (!s.AllowSpawn(now_)) {
    return SendError(s, Code(RejectReason::RateLimited), id, "too many spawns; slow down");
  }
  if ((s.permissions() & kPermissionSpawn) == 0) {
    return SendError(s, Code(RejectReason::NotOwner), id, "the join token does not allow spawning");
  }
  Member* member = room.FindMember(s.player_id());
  if (member == nullptr) return SendError(s, Code(RejectReason::NotJoined), id, "not a member");
  if (id / kEntityIdBlock != member->slot) {
    return SendError(s, Code(RejectReason::NotOwner), id, "entity id outside your id block");
  }
  if (c->owner() != s.player_id()) {
    return SendError(s, Code(RejectReason::NotOwner), id, "container owner must be the sender");
  }
  if (room.FindEntity(id) != nullptr) {
    return SendError(s, Code(RejectReason::DuplicateEntity), id, "entity id already in use");
  }
  if (member->entity_count >= room.config().max_entities_per_player) {
    return SendError(s, Code(RejectReason::EntityLimit), id, "too many entities");
  }
  const schema::Transform* t = c->transform();
  Entity e;
  e.id = id;
  e.owner = s.player_id();
  e.flags = c->flags();
  e.state.entity_id = id;
  e.state.position = {t->position().x(), t->position().y(), t->position().z()};
  e.state.rotation = {t->rotation().x(), t->rotation().y(), t->rotation().z(), t->rotation().w()};
  if (!IsValidState(e.state)) {
    return SendError(s, Code(RejectReason::InvalidMessage), id, "transform not finite or not unit");
  }
  e.changed_at = now_;
  e.creator = s.player_id();
  e.physics = RoomPhysics::RoleOf(*c);
  e.spawn_seq = room.NextSpawnSeq();
  if (e.physics != PhysicsRole::kNone) {
    std::string detail;
    if (room.physics() == nullptr) room.set_physics(MakePhysicsLink(0, now_));
    if (!room.physics()->Add(*c, e.physics, &detail).ok()) {
      return SendError(s, Code(RejectReason::InvalidContainer), id, detail);
    }
    if (e.physics == PhysicsRole::kSimulated) e.owner = 0;  // PhyS is the authority now
  }
  if (auto early = s.early_states().find(id); early != s.early_states().end()) {
    e.state = early->second;  // a state overtook the spawn
    e.version = 2;
    s.early_states().erase(early);
  }
  e.spawn.assign(message.begin(), message.end());
  const bool simulated = e.physics == PhysicsRole::kSimulated;
  if (simulated) {
    // The stored spawn tells every client (the creator included) that PhyS owns it.
    auto* stored = schema::GetMutableControlMessage(e.spawn.data());
    auto* container = static_cast<schema::Spawn*>(stored->mutable_body())->mutable_container();
    container->mutate_owner(0);
  }
  Entity& added = room.AddEntity(std::move(e));
  ++member->entity_count;
  counters_->entities.fetch_add(1, std::memory_order_relaxed);
  BroadcastReliable(room, added.spawn, simulated ? 0 : s.player_id());
}

void Relay::OnDespawn(Session& s, uint32_t entity_id) {
  auto it = rooms_.find(s.room());
  if (it == rooms_.end()) return SendError(s, Code(RejectReason::NotJoined), entity_id, "join a room first");
  Room& room = *it->second;
  Entity* e = room.FindEntity(entity_id);
  if (e == nullptr) return SendError(s, Code(RejectReason::UnknownEntity), entity_id, "no such entity");
  if (e->owner != s.player_id() && !(e->owner == 0 && e->creator == s.player_id())) {
    return SendError(s, Code(RejectReason::NotOwner), entity_id, "not your entity");
  }
  const bool simulated = e->physics == PhysicsRole::kSimulated;
  room.RemoveEntity(entity_id);
  if (Member* m = room.FindMember(s.player_id()); m && m->entity_count > 0) --m->entity_count;
  counters_->entities.fetch_sub(1, std::memory_order_relaxed);
  for (const auto& [pid, m] : room.members()) {
    auto sit = sessions_.find(m.session);
    if (sit != sessions_.end()) sit->second->replicator().Forget(entity_id);
  }
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateDespawn(fbb, entity_id));
  BroadcastReliable(room, {fbb.GetBufferPointer(), fbb.GetSize()}, simulated ? 0 : s.player_id());
}

void Relay::OnGrab(Session& s, uint32_t entity_id, uint32_t hand_id) {
  auto it = rooms_.find(s.room());
  if (it == rooms_.end()) return SendError(s, Code(RejectReason::NotJoined), entity_id, "join a room first");
  Room& room = *it->second;
  Entity* hand = room.FindEntity(hand_id);
  Entity* e = room.FindEntity(entity_id);
  if (hand == nullptr || e == nullptr) {
    return SendError(s, Code(RejectReason::UnknownEntity), e ? hand_id : entity_id, "no such entity");
  }
  if (hand->owner != s.player_id()) {
    return SendError(s, Code(RejectReason::NotOwner), hand_id, "not your hand");
  }
  if (room.physics() == nullptr || e->physics != PhysicsRole::kSimulated) {
    return SendError(s, Code(RejectReason::GrabRefused), entity_id, "not simulated by PhyS");
  }
  e->grab_requester = s.player_id();
  room.physics()->RequestGrab(entity_id, hand_id);  // answered in StepPhysics
}

void Relay::OnRelease(Session& s, uint32_t entity_id) {
  auto it = rooms_.find(s.room());
  if (it == rooms_.end()) return SendError(s, Code(RejectReason::NotJoined), entity_id, "join a room first");
  Room& room = *it->second;
  Entity* e = room.FindEntity(entity_id);
  if (e == nullptr) return SendError(s, Code(RejectReason::UnknownEntity), entity_id, "no such entity");
  Entity* hand = e->held_by != 0 ? room.FindEntity(e->held_by) : nullptr;
  if (hand == nullptr || hand->owner != s.player_id()) {
    return SendError(s, Code(RejectReason::NotOwner), entity_id, "not held by your hand");
  }
  uint32_t hand_id = e->held_by;
  if (room.physics() != nullptr) (void)room.physics()->Release(entity_id);
  e->held_by = 0;
  BroadcastPhysicsEvent(room, schema::PhysicsEventKind::Released, entity_id, hand_id);
}

void Relay::BroadcastPhysicsEvent(Room& room, schema::PhysicsEventKind kind, uint32_t a,
                                  uint32_t b) {
  // Whatever an event names is being interacted with: replication takes it out of the
  // ambient class while a touch is open (Enter without Exit) and for
  // ReplicationConfig::interaction_linger_s after any event.
  using K = schema::PhysicsEventKind;
  const bool enter = kind == K::CollisionEnter || kind == K::TriggerEnter;
  const bool exit = kind == K::CollisionExit || kind == K::TriggerExit;
  for (uint32_t id : {a, b}) {
    Entity* e = id != 0 ? room.FindEntity(id) : nullptr;
    if (e == nullptr) continue;
    e->interacted_at = now_;
    if (enter) ++e->touching;
    if (exit && e->touching > 0) --e->touching;
  }
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreatePhysicsEvent(fbb, kind, a, b));
  BroadcastReliable(room, {fbb.GetBufferPointer(), fbb.GetSize()}, 0);
}

void Relay::StepAllPhysics(double now) {
  physics_rooms_.clear();
  for (auto& [name, room] : rooms_) {
    if (room->physics() == nullptr) continue;
    if (!room->physics()->Healthy(now)) FailOver(*room, now);
    physics_rooms_.push_back(room.get());
  }
  if (physics_rooms_.empty()) return;
  if (step_outputs_.size() < physics_rooms_.size()) step_outputs_.resize(physics_rooms_.size());
  // Worlds step in parallel (each on one thread); results are applied on this thread.
  physics_pool_.Run(physics_rooms_.size(), [this, now](size_t i) {
    physics_rooms_[i]->physics()->Advance(now, &step_outputs_[i]);
  });
  for (size_t i = 0; i < physics_rooms_.size(); ++i) {
    ApplyPhysics(*physics_rooms_[i], step_outputs_[i], now);
  }
}

void Relay::ApplyPhysics(Room& room, const RoomPhysics::StepOutput& out, double now) {
  if (out.steps > 0 && room.physics()->worker() == 0) {
    counters_->physics_step_seconds.Observe(out.step_seconds / out.steps);
    RelayCounters::Inc(counters_->physics_steps, static_cast<uint64_t>(out.steps));
  }
  for (const RoomPhysics::MovedBody& m : out.moved) {
    Entity* e = room.FindEntity(m.state.entity_id);
    if (e == nullptr || e->physics != PhysicsRole::kSimulated || !IsValidState(m.state)) continue;
    e->state = m.state;
    e->linear_velocity = m.linear;
    e->angular_velocity = m.angular;
    ++e->version;
    e->changed_at = now;
  }
  for (const RoomPhysics::SoftNodes& part : out.soft) {
    Entity* e = room.FindEntity(part.id);
    if (e == nullptr || part.total == 0 || part.first + part.nodes.size() > part.total) continue;
    e->nodes.resize(part.total);
    std::copy(part.nodes.begin(), part.nodes.end(), e->nodes.begin() + part.first);
    ++e->nodes_version;
  }
  for (const RoomPhysics::GrabResult& g : out.grabs) {
    Entity* e = room.FindEntity(g.entity);
    if (e == nullptr) continue;
    uint32_t requester = e->grab_requester;
    e->grab_requester = 0;
    if (g.ok) {
      e->held_by = g.hand;
      BroadcastPhysicsEvent(room, schema::PhysicsEventKind::Grabbed, g.entity, g.hand);
    } else if (Member* m = room.FindMember(requester)) {
      auto sit = sessions_.find(m->session);
      if (sit != sessions_.end()) {
        SendError(*sit->second, Code(RejectReason::GrabRefused), g.entity, g.detail);
      }
    }
  }
  for (const physics::PhysicsEvent& ev : out.events) {
    using T = physics::PhysicsEventType;
    if ((ev.type == T::kCollisionEnter || ev.type == T::kCollisionExit) &&
        !ReportsContacts(room.FindEntity(ev.entity_a)) &&
        !ReportsContacts(room.FindEntity(ev.entity_b))) {
      continue;  // a contact nobody asked about (a pile of boxes) stays inside PhyS
    }
    schema::PhysicsEventKind kind = schema::PhysicsEventKind::CollisionEnter;
    switch (ev.type) {
      case T::kCollisionEnter: kind = schema::PhysicsEventKind::CollisionEnter; break;
      case T::kCollisionExit: kind = schema::PhysicsEventKind::CollisionExit; break;
      case T::kTriggerEnter: kind = schema::PhysicsEventKind::TriggerEnter; break;
      case T::kTriggerExit: kind = schema::PhysicsEventKind::TriggerExit; break;
      case T::kGuardReset:
        kind = schema::PhysicsEventKind::GuardReset;
        RelayCounters::Inc(counters_->guard_resets);
        break;
    }
    BroadcastPhysicsEvent(room, kind, ev.entity_a, ev.entity_b);
  }
}

std::unique_ptr<PhysicsLink> Relay::MakePhysicsLink(uint32_t exclude_worker, double now) {
  // The least loaded healthy worker, else embedded.
  Session* best = nullptr;
  size_t best_rooms = 0;
  for (auto& [id, s] : sessions_) {
    if (!s->is_worker() || id == exclude_worker || !s->connection().connected()) continue;
    size_t rooms = 0;
    for (auto& [name, r] : rooms_) {
      if (r->physics() != nullptr && r->physics()->worker() == id) ++rooms;
    }
    if (best == nullptr || rooms < best_rooms) {
      best = s.get();
      best_rooms = rooms;
    }
  }
  if (best == nullptr) return std::make_unique<EmbeddedPhysicsLink>(config_.physics, now);
  uint32_t handle = ++next_room_handle_;
  spdlog::info("PhyS: room handle {} on worker {:08x}", handle, best->connection().id());
  return std::make_unique<RemotePhysicsLink>(best, best->connection().id(), handle, config_.physics,
                                             now);
}

void Relay::FailOver(Room& room, double now) {
  std::unique_ptr<PhysicsLink> old = room.TakePhysics();
  uint32_t dead_worker = old ? old->worker() : 0;
  if (auto* remote = dynamic_cast<RemotePhysicsLink*>(old.get())) remote->Detach();
  old.reset();
  room.set_physics(MakePhysicsLink(dead_worker, now));
  PhysicsLink& link = *room.physics();
  std::vector<Entity*> order;
  for (const auto& [id, e] : room.entities()) {
    if (e.physics != PhysicsRole::kNone) order.push_back(room.FindEntity(id));
  }
  std::sort(order.begin(), order.end(),
            [](const Entity* a, const Entity* b) { return a->spawn_seq < b->spawn_seq; });
  for (Entity* e : order) {
    e->touching = 0;  // the new world reports its overlaps afresh
    const auto* msg = schema::GetControlMessage(e->spawn.data());
    const schema::Container* c = msg->body_as_Spawn()->container();
    std::string detail;
    if (!link.Add(*c, e->physics, &detail).ok()) {
      spdlog::error("failover of room '{}': entity {} not restored: {}", room.name(), e->id, detail);
      continue;
    }
    if (e->physics == PhysicsRole::kSimulated) {
      link.Restore(e->id, e->state, e->linear_velocity, e->angular_velocity);
    } else {
      link.Drive(e->id, e->state);
    }
  }
  for (Entity* e : order) {
    if (e->held_by != 0) link.RequestGrab(e->id, e->held_by, /*force=*/true);
  }
  RelayCounters::Inc(counters_->physics_failovers);
  spdlog::warn("PhyS for room '{}' failed over from {} to {} ({} entities)", room.name(),
               dead_worker ? "a worker" : "embedded", link.worker() ? "another worker" : "embedded",
               order.size());
}

void Relay::OnWorkerHello(Session& s) {
  if ((s.permissions() & kPermissionWorker) == 0) {
    return SendError(s, Code(RejectReason::NotOwner), 0, "the token is not a worker token");
  }
  if (s.is_worker()) return;
  s.set_worker(true);
  s.connection().SetTimeout(kWorkerTimeoutS);
  counters_->physics_workers.fetch_add(1, std::memory_order_relaxed);
  spdlog::info("PhyS worker {:08x} attached from {}:{}", s.connection().id(),
               s.endpoint().address().to_string(), s.endpoint().port());
}

void Relay::OnWorkerResult(Session& s, const schema::WorkerResult& result) {
  if (!s.is_worker()) return;
  for (auto& [name, room] : rooms_) {
    auto* remote = dynamic_cast<RemotePhysicsLink*>(room->physics());
    if (remote != nullptr && remote->worker() == s.connection().id() &&
        remote->handle() == result.room()) {
      remote->ReceiveResult(result, now_);
      return;
    }
  }
}

void Relay::OnWorkerStates(Session& s, std::span<const uint8_t> payload) {
  if (payload.size() < 5) return;
  uint32_t handle = LoadU32LE(payload.data() + 1);
  for (auto& [name, room] : rooms_) {
    auto* remote = dynamic_cast<RemotePhysicsLink*>(room->physics());
    if (remote != nullptr && remote->worker() == s.connection().id() && remote->handle() == handle) {
      remote->ReceiveStates(payload, now_);
      return;
    }
  }
}

void Relay::OnStates(Session& s, std::span<const uint8_t> payload) {
  if (s.is_worker()) return OnWorkerStates(s, payload);
  auto it = rooms_.find(s.room());
  if (it == rooms_.end()) {
    counters_->RejectUpdate(DropReason::kNotJoined);
    return;
  }
  if (!DecodeStateBatch(payload, &batch_).ok()) {
    counters_->RejectPacket(DropReason::kMalformed);
    Log().Note("state payload dropped", DropReasonName(DropReason::kMalformed), s.endpoint(), now_);
    return;
  }
  Room& room = *it->second;
  for (const EntityState& st : batch_.states) {
    Entity* e = room.FindEntity(st.entity_id);
    DropReason reject = DropReason::kCount;
    if (e == nullptr) {
      const Member* m = room.FindMember(s.player_id());
      if (m != nullptr && st.entity_id / kEntityIdBlock == m->slot && IsValidState(st) &&
          (s.early_states().size() < kMaxEarlyStates || s.early_states().count(st.entity_id))) {
        s.early_states()[st.entity_id] = st;  // its spawn is still on the way
        continue;
      }
      reject = DropReason::kUnknownEntity;
    } else if (e->owner != s.player_id()) {
      reject = DropReason::kNotOwner;
    } else if (!IsValidState(st)) {
      reject = DropReason::kInvalidValue;
    }
    if (reject != DropReason::kCount) {
      counters_->RejectUpdate(reject);
      Log().Note("entity update dropped", DropReasonName(reject), s.endpoint(), now_);
      continue;
    }
    e->state = st;
    ++e->version;
    e->changed_at = now_;
    if (e->physics == PhysicsRole::kMirrored && room.physics() != nullptr) {
      room.physics()->Drive(st.entity_id, st);
    }
    RelayCounters::Inc(counters_->entity_updates_received);
  }
}

void Relay::TickDueRooms(double now) {
  // Every due room's clients are independent: each ClientReplicator reads its room's entities
  // (unchanged during the tick) and writes only its own session. They run on the pool; their
  // datagrams are queued per session and sent from this thread afterwards.
  tick_jobs_.clear();
  auto start = std::chrono::steady_clock::now();
  size_t due_rooms = 0;
  for (auto& [name, room] : rooms_) {
    if (now < room->next_tick()) continue;
    ++due_rooms;
    room->PrepareStates();  // once per changed entity, not once per receiver
    for (const auto& [pid, member] : room->members()) {
      auto sit = sessions_.find(member.session);
      if (sit == sessions_.end() || !sit->second->connection().connected()) continue;
      if (!sit->second->ReadyForStates()) continue;  // Joined not acknowledged yet
      tick_jobs_.push_back({room.get(), sit->second.get()});
    }
    room->ScheduleNextTick(now);
  }
  if (due_rooms == 0) return;
  // Serial: send as we go. Parallel: queue per session, send after the join.
  const bool parallel = physics_pool_.threads() > 1 && tick_jobs_.size() > 1;
  for (const TickJob& job : tick_jobs_) job.session->set_buffering(parallel);
  physics_pool_.Run(tick_jobs_.size(), [this, now](size_t i) {
    Session& s = *tick_jobs_[i].session;
    s.replicator().Tick(tick_jobs_[i].room->entities(), s.player_id(), now, s.connection(), s,
                        *counters_);
  });
  for (const TickJob& job : tick_jobs_) {
    job.session->set_buffering(false);
    job.session->FlushOutbox();
  }
  double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  counters_->tick_seconds.Observe(seconds / static_cast<double>(due_rooms));
}

void Relay::BroadcastReliable(Room& room, std::span<const uint8_t> message,
                              uint32_t except_player) {
  for (const auto& [pid, m] : room.members()) {
    if (pid == except_player) continue;
    auto it = sessions_.find(m.session);
    if (it == sessions_.end()) continue;
    Session& s = *it->second;
    if (!s.connection().SendReliable(message).ok()) {
      s.connection().Disconnect(DisconnectReason::kReliableOverflow, s);
    }
  }
}

void Relay::RemoveSession(uint32_t connection_id, double now) {
  auto it = sessions_.find(connection_id);
  if (it == sessions_.end()) return;
  Session& s = *it->second;
  if (!s.room().empty()) OnLeaveRoom(s, now);
  if (s.is_worker()) {
    counters_->physics_workers.fetch_sub(1, std::memory_order_relaxed);
    spdlog::warn("PhyS worker {:08x} lost ({})", connection_id,
                 static_cast<int>(s.connection().disconnect_reason()));
    for (auto& [name, room] : rooms_) {
      if (room->physics() != nullptr && room->physics()->worker() == connection_id) {
        FailOver(*room, now);
      }
    }
  }
  DisconnectReason reason = s.connection().disconnect_reason();
  counters_->CountDisconnect(reason);
  spdlog::info("player {} disconnected (reason {})", s.player_id(), static_cast<int>(reason));
  auto eit = session_by_endpoint_.find(s.endpoint());
  if (eit != session_by_endpoint_.end() && eit->second == connection_id) {
    session_by_endpoint_.erase(eit);
  }
  sessions_.erase(it);
}

void Relay::CloseIdleRooms(double now) {
  for (auto it = rooms_.begin(); it != rooms_.end();) {
    Room& room = *it->second;
    if (room.empty() && now - room.empty_since() >= room.config().idle_ttl_s) {
      counters_->entities.fetch_sub(static_cast<int64_t>(room.entities().size()),
                                    std::memory_order_relaxed);
      spdlog::info("room '{}' closed after {:.0f} s empty", room.name(), now - room.empty_since());
      it = rooms_.erase(it);
    } else {
      ++it;
    }
  }
}

void Relay::Shutdown() {
  for (auto& [id, s] : sessions_) s->connection().Disconnect(DisconnectReason::kServerShutdown, *s);
  while (!sessions_.empty()) RemoveSession(sessions_.begin()->first, now_);
  if (shard_.shared_counters) PublishGauge(counters_->clients, &published_clients_, 0);
}

const Room* Relay::FindRoom(const std::string& name) const {
  auto it = rooms_.find(name);
  return it == rooms_.end() ? nullptr : it->second.get();
}

uint32_t Relay::PhysicsWorkerOf(const std::string& room) const {
  auto it = rooms_.find(room);
  if (it == rooms_.end() || it->second->physics() == nullptr) return 0;
  return it->second->physics()->worker();
}

const ConnectionStats* Relay::FindConnectionStats(uint32_t player_id) const {
  for (const auto& [id, s] : sessions_) {
    if (s->player_id() == player_id) return &s->connection().stats();
  }
  return nullptr;
}

size_t Relay::ReplicatedEntityCount(uint32_t player_id) const {
  for (const auto& [id, s] : sessions_) {
    if (s->player_id() == player_id) return s->replicator().tracked_entities();
  }
  return 0;
}

}  // namespace edgephys
