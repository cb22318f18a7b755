#include "relay/admin/room_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

namespace edgephys::admin {
namespace {

using nlohmann::json;

constexpr uint32_t kFlagAvatar = 1u << 3;  // schema::EntityFlags::Avatar
constexpr uint32_t kFlagHand = 1u << 4;    // schema::EntityFlags::Hand

// Positions are validated finite when accepted; null guards JSON (no NaN) all the same.
json Coordinate(float v) { return std::isfinite(v) ? json(v) : json(nullptr); }

}  // namespace

const char* MapKindName(MapKind kind) {
  switch (kind) {
    case MapKind::kAvatar: return "avatar";
    case MapKind::kHand: return "hand";
    case MapKind::kPhysicsBody: return "physics_body";
    case MapKind::kSoftBody: return "soft_body";
    case MapKind::kObject: break;
  }
  return "object";
}

MapKind MapKindOf(const Entity& e) {
  if (e.cost.particles > 0 || !e.nodes.empty()) return MapKind::kSoftBody;
  if (e.flags & kFlagHand) return MapKind::kHand;
  if (e.flags & kFlagAvatar) return MapKind::kAvatar;
  if (e.physics == PhysicsRole::kSimulated) return MapKind::kPhysicsBody;
  return MapKind::kObject;
}

RoomMapSnapshot TakeRoomMap(const Room& room, size_t limit) {
  RoomMapSnapshot map;
  map.room = room.name();
  map.limit = limit;
  map.total = room.entities().size();
  for (const auto& [player, member] : room.members()) map.players.push_back(player);
  // (rank, entity): players' hands and avatars first, then by id.
  std::vector<std::pair<int, const Entity*>> order;
  order.reserve(room.entities().size());
  float lo[3], hi[3];
  std::fill(lo, lo + 3, std::numeric_limits<float>::infinity());
  std::fill(hi, hi + 3, -std::numeric_limits<float>::infinity());
  for (const auto& [id, e] : room.entities()) {
    order.emplace_back((e.flags & (kFlagAvatar | kFlagHand)) != 0 ? 0 : 1, &e);
    const float p[3] = {e.state.position.x, e.state.position.y, e.state.position.z};
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(p[i])) continue;
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  }
  const size_t listed = std::min(limit, order.size());
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(listed), order.end(),
                    [](const auto& a, const auto& b) {
                      return a.first != b.first ? a.first < b.first : a.second->id < b.second->id;
                    });
  map.entities.reserve(listed);
  for (size_t i = 0; i < listed; ++i) {
    const Entity& e = *order[i].second;
    map.entities.push_back({e.id, e.owner, e.creator, MapKindOf(e),
                            e.physics == PhysicsRole::kSimulated, e.state.position});
  }
  map.has_bounds = lo[0] <= hi[0] && lo[1] <= hi[1] && lo[2] <= hi[2];
  if (map.has_bounds) {
    map.min = {lo[0], lo[1], lo[2]};
    map.max = {hi[0], hi[1], hi[2]};
  }
  return map;
}

json RoomMapJson(const RoomMapSnapshot& map) {
  json entities = json::array();
  for (const RoomMapSnapshot::Item& e : map.entities) {
    entities.push_back({{"id", e.id},
                        {"owner", e.owner},
                        {"creator", e.creator},
                        {"kind", MapKindName(e.kind)},
                        {"x", Coordinate(e.position.x)},
                        {"y", Coordinate(e.position.y)},
                        {"z", Coordinate(e.position.z)},
                        {"simulated", e.simulated}});
  }
  json bounds = nullptr;
  if (map.has_bounds) {
    bounds = {{"min", {map.min.x, map.min.y, map.min.z}}, {"max", {map.max.x, map.max.y, map.max.z}}};
  }
  return {{"room", map.room},
          {"entities", std::move(entities)},
          {"listed", map.entities.size()},
          {"total", map.total},
          {"truncated", map.entities.size() < map.total},
          {"limit", map.limit},
          {"players", map.players},
          {"bounds", std::move(bounds)}};
}

}  // namespace edgephys::admin
