#include "relay/admin/room_map.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>
#include <vector>

namespace edgephys::admin {
namespace {

using nlohmann::json;

constexpr uint32_t kFlagAvatar = 1u << 3;  // schema::EntityFlags::Avatar
constexpr uint32_t kFlagHand = 1u << 4;    // schema::EntityFlags::Hand

// Positions are validated finite when accepted; null guards JSON (no NaN) all the same.
json Coordinate(float v) { return std::isfinite(v) ? json(v) : json(nullptr); }

}  // namespace

const char* MapKindOf(const Entity& e) {
  if (e.cost.particles > 0 || !e.nodes.empty()) return "soft_body";
  if (e.flags & kFlagHand) return "hand";
  if (e.flags & kFlagAvatar) return "avatar";
  if (e.physics == PhysicsRole::kSimulated) return "physics_body";
  return "object";
}

json RoomMapJson(const Room& room, size_t limit) {
  // (rank, id): players' hands and avatars first.
  std::vector<std::pair<int, const Entity*>> order;
  order.reserve(room.entities().size());
  float lo[3], hi[3];
  std::fill(lo, lo + 3, std::numeric_limits<float>::infinity());
  std::fill(hi, hi + 3, -std::numeric_limits<float>::infinity());
  for (const auto& [id, e] : room.entities()) {
    const int rank = (e.flags & (kFlagAvatar | kFlagHand)) != 0 ? 0 : 1;
    order.emplace_back(rank, &e);
    const float p[3] = {e.state.position.x, e.state.position.y, e.state.position.z};
    for (int i = 0; i < 3; ++i) {
      if (!std::isfinite(p[i])) continue;
      lo[i] = std::min(lo[i], p[i]);
      hi[i] = std::max(hi[i], p[i]);
    }
  }
  auto before = [](const std::pair<int, const Entity*>& a, const std::pair<int, const Entity*>& b) {
    return a.first != b.first ? a.first < b.first : a.second->id < b.second->id;
  };
  const size_t listed = std::min(limit, order.size());
  std::partial_sort(order.begin(), order.begin() + static_cast<std::ptrdiff_t>(listed), order.end(),
                    before);
  json entities = json::array();
  for (size_t i = 0; i < listed; ++i) {
    const Entity& e = *order[i].second;
    entities.push_back({{"id", e.id},
                        {"owner", e.owner},
                        {"creator", e.creator},
                        {"kind", MapKindOf(e)},
                        {"x", Coordinate(e.state.position.x)},
                        {"y", Coordinate(e.state.position.y)},
                        {"z", Coordinate(e.state.position.z)},
                        {"simulated", e.physics == PhysicsRole::kSimulated}});
  }
  json players = json::array();
  for (const auto& [player, member] : room.members()) players.push_back(player);
  json bounds = nullptr;
  if (lo[0] <= hi[0]) bounds = {{"min", {lo[0], lo[1], lo[2]}}, {"max", {hi[0], hi[1], hi[2]}}};
  return {{"room", room.name()},
          {"entities", std::move(entities)},
          {"listed", listed},
          {"total", order.size()},
          {"truncated", listed < order.size()},
          {"limit", limit},
          {"players", std::move(players)},
          {"bounds", std::move(bounds)}};
}

}  // namespace edgephys::admin
