#include "relay/admin/room_inspector.h"

#include <cmath>
#include <map>

#include "relay/admin/room_request.h"

namespace edgephys::admin {
namespace {

using nlohmann::json;

// NaN (unknown) as null: JSON has no NaN.
json Number(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

}  // namespace

void RoomInspector::Sample(const Relay& relay, double now) {
  std::unordered_map<uint32_t, Rate> next;
  for (const auto& [name, room] : relay.rooms()) {
    for (const auto& [player, member] : room->room().members()) {
      const Session* s = relay.FindMemberSession(name, player);
      if (s == nullptr) continue;
      const ConnectionStats& st = s->connection().stats();
      Rate r{st.bytes_received, st.bytes_sent, now, 0, 0};
      if (auto it = rates_.find(s->connection().id()); it != rates_.end() && now > it->second.at) {
        double dt = now - it->second.at;
        r.in_per_s = static_cast<double>(st.bytes_received - it->second.bytes_in) / dt;
        r.out_per_s = static_cast<double>(st.bytes_sent - it->second.bytes_out) / dt;
      }
      next[s->connection().id()] = r;
    }
  }
  rates_ = std::move(next);
}

const RoomInspector::Rate* RoomInspector::RateOf(uint32_t connection_id) const {
  auto it = rates_.find(connection_id);
  return it == rates_.end() ? nullptr : &it->second;
}

json RoomInspector::Summary(const Relay& relay, const RoomHost& host) const {
  const Room& room = host.room();
  double in = 0, out = 0;
  for (const auto& [player, member] : room.members()) {
    const Session* s = relay.FindMemberSession(room.name(), player);
    if (const Rate* r = s ? RateOf(s->connection().id()) : nullptr; r != nullptr) {
      in += r->in_per_s;
      out += r->out_per_s;
    }
  }
  const PhysicsLink* physics = room.physics();
  json phys = {{"enabled", room.config().physics},
               {"active", physics != nullptr},
               {"realtime_factor", physics ? Number(physics->realtime_factor()) : json(nullptr)},
               {"worker", physics && physics->worker() != 0 ? json(physics->worker()) : json(nullptr)}};
  return {{"id", room.name()},
          {"players", room.size()},
          {"capacity", room.config().capacity},
          {"entities", room.entities().size()},
          {"physics", std::move(phys)},
          {"tick_rate_hz", room.config().tick_rate_hz},
          {"state_format", host.state_format()},
          {"bytes_in_per_s", in},
          {"bytes_out_per_s", out}};
}

json RoomInspector::ListRooms(const Relay& relay) const {
  json rooms = json::array();
  for (const auto& [name, room] : relay.rooms()) rooms.push_back(Summary(relay, *room));
  return {{"rooms", std::move(rooms)}};
}

std::optional<json> RoomInspector::DescribeRoom(const Relay& relay, const std::string& id,
                                                double now) const {
  auto it = relay.rooms().find(id);
  if (it == relay.rooms().end()) return std::nullopt;
  const Room& room = it->second->room();
  json view = Summary(relay, *it->second);
  view["config"] = RoomConfigJson(room.config());
  std::map<uint32_t, size_t> by_owner;
  for (const auto& [eid, e] : room.entities()) ++by_owner[e.owner];
  json members = json::array();
  for (const auto& [player, member] : room.members()) {
    const Session* s = relay.FindMemberSession(id, player);
    if (s == nullptr) continue;
    const ConnectionStats& st = s->connection().stats();
    const Rate* r = RateOf(s->connection().id());
    auto owned = by_owner.find(player);
    members.push_back({{"player_id", player},
                       {"connection_id", s->connection().id()},
                       {"address", s->endpoint().address().to_string() + ":" +
                                       std::to_string(s->endpoint().port())},
                       {"rtt_ms", st.rtt_s * 1000},
                       {"rtt_var_ms", st.rtt_var_s * 1000},
                       {"loss", st.loss},
                       {"bytes_in_per_s", r ? r->in_per_s : 0.0},
                       {"bytes_out_per_s", r ? r->out_per_s : 0.0},
                       {"pending_reliable_bytes", st.pending_reliable_bytes},
                       {"connected_for_s", now - s->connected_at()},
                       {"entities", owned == by_owner.end() ? 0 : owned->second}});
  }
  json owners = json::array();
  for (const auto& [owner, count] : by_owner) owners.push_back({{"owner", owner}, {"count", count}});
  view["members"] = std::move(members);
  view["entities_by_owner"] = std::move(owners);
  return view;
}

}  // namespace edgephys::admin
