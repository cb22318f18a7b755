#include "relay/room_budget.h"

namespace edgephys {
namespace {

template <typename T>
bool Over(T used, T add, T limit) {
  return limit != 0 && used + add > limit;
}

}  // namespace

EntityCost EntityCost::Of(const schema::Container& c, size_t message_bytes, bool physics) {
  EntityCost cost;
  cost.entities = 1;
  cost.bytes = message_bytes;
  if (!physics) return cost;
  const bool colliders = c.colliders() != nullptr && c.colliders()->size() != 0;
  if (c.soft_body() != nullptr) {
    cost.bodies = 1;
    const auto* p = c.soft_body()->particles();
    cost.particles = p == nullptr ? 0 : static_cast<uint32_t>(p->size() / 3);
    return cost;
  }
  if (c.rigid_body() != nullptr || colliders) cost.bodies = 1;
  cost.joints = c.joints() == nullptr ? 0 : static_cast<uint32_t>(c.joints()->size());
  return cost;
}

void EntityCost::Add(const EntityCost& o) {
  entities += o.entities;
  bodies += o.bodies;
  particles += o.particles;
  joints += o.joints;
  bytes += o.bytes;
}

void EntityCost::Subtract(const EntityCost& o) {
  auto sub = [](auto& a, auto b) { a = a > b ? a - b : 0; };
  sub(entities, o.entities);
  sub(bodies, o.bodies);
  sub(particles, o.particles);
  sub(joints, o.joints);
  sub(bytes, o.bytes);
}

BudgetKind RoomLedger::Check(uint32_t player, const EntityCost& cost, size_t name_bytes) const {
  const RoomBudgets& b = budgets_;
  if (b.max_name_bytes != 0 && name_bytes > b.max_name_bytes) return BudgetKind::kNameLength;
  const EntityCost mine = Of(player);
  if (Over(mine.entities, cost.entities, max_entities_per_player_)) {
    return BudgetKind::kPlayerEntities;
  }
  if (Over(total_.entities, cost.entities, b.max_entities)) return BudgetKind::kRoomEntities;
  if (Over(mine.bytes, cost.bytes, b.max_bytes_per_player)) return BudgetKind::kPlayerBytes;
  if (Over(total_.bytes, cost.bytes, b.max_bytes)) return BudgetKind::kRoomBytes;
  if (Over(mine.bodies, cost.bodies, b.max_bodies_per_player)) return BudgetKind::kPlayerBodies;
  if (Over(total_.bodies, cost.bodies, b.max_bodies)) return BudgetKind::kRoomBodies;
  if (Over(mine.particles, cost.particles, b.max_particles_per_player)) {
    return BudgetKind::kPlayerParticles;
  }
  if (Over(total_.particles, cost.particles, b.max_particles)) return BudgetKind::kRoomParticles;
  if (Over(mine.joints, cost.joints, b.max_joints_per_player)) return BudgetKind::kPlayerJoints;
  if (Over(total_.joints, cost.joints, b.max_joints)) return BudgetKind::kRoomJoints;
  return BudgetKind::kNone;
}

void RoomLedger::Charge(uint32_t player, const EntityCost& cost) {
  by_player_[player].Add(cost);
  total_.Add(cost);
}

void RoomLedger::Refund(uint32_t player, const EntityCost& cost) {
  total_.Subtract(cost);
  auto it = by_player_.find(player);
  if (it == by_player_.end()) return;
  it->second.Subtract(cost);
  if (it->second.entities == 0) by_player_.erase(it);
}

EntityCost RoomLedger::Of(uint32_t player) const {
  auto it = by_player_.find(player);
  return it == by_player_.end() ? EntityCost{} : it->second;
}

}  // namespace edgephys
