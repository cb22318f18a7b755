// Relay: rooms and membership (creating, joining, leaving, closing idle rooms) and the
// operator's actions and lookups (kick, close a room, close every session, find a member).
// The loop is in relay.cc, the handshake and admission in relay_handshake.cc.
#include <spdlog/spdlog.h>

#include <limits>

#include "relay/relay.h"

namespace edgephys {

using schema::RejectReason;

RoomHost& Relay::GetOrCreateRoom(const std::string& name, double now) {
  auto it = rooms_.find(name);
  if (it != rooms_.end()) return *it->second;
  auto& room = rooms_[name];
  room = std::make_unique<RoomHost>(name, config_.room_defaults, room_env(), now);
  spdlog::info("room '{}' created", name);
  return *room;
}

Status Relay::CreateRoom(const std::string& name, const RoomConfig& config, double now) {
  if (name.empty() || name.size() > kMaxRoomNameSize) {
    return Status::InvalidArgument("room name must be 1..64 bytes");
  }
  if (config.capacity == 0 || config.capacity >= kEntityIdBlock || config.tick_rate_hz <= 0 ||
      config.tick_rate_hz > 1000) {
    return Status::InvalidArgument("room capacity or tick rate out of range");
  }
  if (!admitting_) return Status::ResourceExhausted("the relay is draining");
  auto it = rooms_.find(name);
  if (it != rooms_.end()) {
    if (it->second->in_use()) return Status::AlreadyExists("room is in use");
    ForgetRoomWork(*it->second);
    rooms_.erase(it);
  }
  rooms_[name] = std::make_unique<RoomHost>(name, config, room_env(), now);
  return Status::Ok();
}

void Relay::OnJoinRoom(Session& s, std::string_view room_name, double now) {
  if (s.room() != nullptr && s.room()->name() == room_name) return;  // already there
  if (room_name.empty() || room_name.size() > kMaxRoomNameSize) {
    return s.SendError(RejectReason::InvalidMessage, 0, "room name must be 1..64 bytes");
  }
  if (room_name != s.token_room()) {
    return s.SendError(RejectReason::WrongRoom, 0, "the join token does not grant this room");
  }
  if (!admitting_) return s.SendError(RejectReason::ServerFull, 0, "the relay is draining");
  if (s.room() != nullptr) OnLeaveRoom(s, now);
  RoomHost& room = GetOrCreateRoom(std::string(room_name), now);
  // The same player connected twice (e.g. a new device): the newer session wins.
  if (MemberLink* old = room.FindMember(s.player_id()); old != nullptr && old != &s) {
    // Every MemberLink of this relay's rooms is one of its Sessions (RoomHost::Join is only
    // called with sessions), so this downcast names the older session to remove.
    Session& old_session = static_cast<Session&>(*old);
    old_session.connection().Disconnect(DisconnectReason::kKicked, old_session);
    RemoveSession(old_session.connection().id(), now);
  }
  if (room.Join(s, now)) s.set_room(&room);
}

void Relay::OnLeaveRoom(Session& s, double now) {
  RoomHost* room = s.room();
  s.set_room(nullptr);
  if (room != nullptr) room->Leave(s, now);
}

void Relay::CloseIdleRooms(double now) {
  for (auto it = rooms_.begin(); it != rooms_.end();) {
    const Room& room = it->second->room();
    if (it->second->IdleExpired(now)) {
      counters_->entities.fetch_sub(static_cast<int64_t>(room.entities().size()),
                                    std::memory_order_relaxed);
      spdlog::info("room '{}' closed after {:.0f} s empty", room.name(), now - room.empty_since());
      ForgetRoomWork(*it->second);
      it = rooms_.erase(it);
    } else {
      ++it;
    }
  }
}

const Room* Relay::FindRoom(const std::string& name) const {
  auto it = rooms_.find(name);
  return it == rooms_.end() ? nullptr : &it->second->room();
}

uint32_t Relay::PhysicsWorkerOf(const std::string& room) const {
  auto it = rooms_.find(room);
  return it == rooms_.end() ? 0 : it->second->physics_worker();
}

const ConnectionStats* Relay::FindConnectionStats(uint32_t player_id) const {
  for (const auto& [id, s] : sessions_) {
    if (s->player_id() == player_id) return &s->connection().stats();
  }
  return nullptr;
}

const Session* Relay::FindMemberSession(const std::string& room, uint32_t player_id) const {
  auto it = rooms_.find(room);
  if (it == rooms_.end()) return nullptr;
  // Every MemberLink of this relay's rooms is one of its Sessions (see OnJoinRoom).
  return static_cast<const Session*>(it->second->FindMember(player_id));
}

Status Relay::Kick(const std::string& room, uint32_t player_id, std::string_view reason,
                   double now) {
  auto* s = const_cast<Session*>(FindMemberSession(room, player_id));
  if (s == nullptr) return Status::NotFound("no such member");
  s->BeginClose(DisconnectReason::kKicked, reason, now);
  sessions_deadline_ = -std::numeric_limits<double>::infinity();
  OnLeaveRoom(*s, now);
  spdlog::info("player {} kicked from room '{}': {}", player_id, room, reason);
  return Status::Ok();
}

Status Relay::CloseRoom(const std::string& name, std::string_view reason, double now) {
  auto it = rooms_.find(name);
  if (it == rooms_.end()) return Status::NotFound("no such room");
  std::vector<uint32_t> players;
  for (const auto& [player, member] : it->second->room().members()) players.push_back(player);
  for (uint32_t player : players) (void)Kick(name, player, reason, now);
  counters_->entities.fetch_sub(static_cast<int64_t>(it->second->room().entities().size()),
                                std::memory_order_relaxed);
  ForgetRoomWork(*it->second);
  rooms_.erase(it);
  spdlog::info("room '{}' closed by the operator: {}", name, reason);
  return Status::Ok();
}

void Relay::HandOverRoom(const std::string& name, std::string_view reason, double now) {
  auto it = rooms_.find(name);
  if (it == rooms_.end()) return;
  std::vector<uint32_t> players;
  for (const auto& [player, member] : it->second->room().members()) players.push_back(player);
  for (uint32_t player : players) {
    auto* s = const_cast<Session*>(FindMemberSession(name, player));
    if (s == nullptr) continue;
    s->BeginClose(DisconnectReason::kServerShutdown, reason, now);
    OnLeaveRoom(*s, now);
  }
  sessions_deadline_ = -std::numeric_limits<double>::infinity();
  counters_->entities.fetch_sub(static_cast<int64_t>(it->second->room().entities().size()),
                                std::memory_order_relaxed);
  ForgetRoomWork(*it->second);
  rooms_.erase(it);
  spdlog::warn("room '{}' handed over: {} ({} members sent on)", name, reason, players.size());
}

void Relay::CloseAllSessions(std::string_view reason, double now) {
  for (auto& [id, s] : sessions_) {
    if (s->is_worker()) continue;
    s->BeginClose(DisconnectReason::kServerShutdown, reason, now);
    if (s->room() != nullptr) OnLeaveRoom(*s, now);
  }
  sessions_deadline_ = -std::numeric_limits<double>::infinity();
}

size_t Relay::client_count() const {
  size_t n = 0;
  for (const auto& [id, s] : sessions_) n += !s->is_worker();
  return n;
}

size_t Relay::ReplicatedEntityCount(uint32_t player_id) const {
  for (const auto& [id, s] : sessions_) {
    if (s->player_id() == player_id && s->room() != nullptr) {
      return s->replicator().tracked_entities();
    }
  }
  return 0;
}

}  // namespace edgephys
