// What a room's entities cost, and the budgets that bound it: per player identity (the join
// token's player id, so a leave and rejoin does not reset it; entities that outlive their
// creator as Persistent keep counting against the creator until despawned) and per room.
// Covers the relay's own state (entities, stored container bytes, name lengths) and PhyS work
// (bodies, soft-body particles, joints), whether PhyS runs embedded or on a worker.
//
// Thread-safety: none (the room's thread). Cost: O(1) per call, a map entry per creator.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string_view>
#include <unordered_map>

#include "edgephys/schema/container_generated.h"

namespace edgephys {

// Limits of one room (RoomConfig::budgets); 0 disables a limit. Per-player limits apply to
// each player identity, room limits to the sum over everyone.
struct RoomBudgets {
  uint32_t max_entities = 16384;                    // room (per player: max_entities_per_player)
  uint32_t max_bodies_per_player = 256;             // PhyS bodies (rigid, mirrored, soft)
  uint32_t max_bodies = 4096;
  uint32_t max_particles_per_player = 8192;         // soft-body particles
  uint32_t max_particles = 32768;
  uint32_t max_joints_per_player = 256;
  uint32_t max_joints = 2048;
  size_t max_bytes_per_player = 16u << 20;          // stored spawn messages (late-join state)
  size_t max_bytes = 64u << 20;
  size_t max_name_bytes = 1024;                     // Container.name, per entity
  // Application messages (RoomHost::Message): one payload's size, and rates (sustained; bursts
  // of 2 s allowed) per player and for the room's senders together.
  size_t max_message_bytes = 64u << 10;
  double messages_per_s_per_player = 120;
  double message_bytes_per_s_per_player = 256u << 10;
  double messages_per_s = 2000;
  double message_bytes_per_s = 4u << 20;
  // Properties (RoomHost::SetProperty): how many the room holds (room and entity properties
  // together), their key and value bytes in all, one string/bytes value's size, and writes per
  // second per player (sustained; bursts of 2 s allowed).
  uint32_t max_properties = 4096;
  size_t max_property_bytes = 1u << 20;
  size_t max_property_value_bytes = 16u << 10;
  double property_writes_per_s_per_player = 120;
  // Ownership requests (RoomHost::Ownership: requests, hand overs, releases, takeover
  // settings) per second per player (sustained; bursts of 2 s allowed).
  double ownership_requests_per_s_per_player = 60;

  // Every limit off (benchmarks that build large scenes on purpose).
  static RoomBudgets Unlimited() {
    RoomBudgets b;
    b.max_entities = b.max_bodies_per_player = b.max_bodies = 0;
    b.max_particles_per_player = b.max_particles = b.max_joints_per_player = b.max_joints = 0;
    b.max_bytes_per_player = b.max_bytes = b.max_name_bytes = 0;
    b.messages_per_s_per_player = b.message_bytes_per_s_per_player = 0;
    b.messages_per_s = b.message_bytes_per_s = 0;
    b.max_properties = 0;
    b.max_property_bytes = b.max_property_value_bytes = 0;
    b.property_writes_per_s_per_player = 0;
    b.ownership_requests_per_s_per_player = 0;
    return b;
  }
};

// Why a spawn or a property write was refused by a budget: the label of edgephys_budget_refusals_total.
enum class BudgetKind : uint8_t {
  kPlayerEntities, kRoomEntities, kPlayerBodies, kRoomBodies, kPlayerParticles, kRoomParticles,
  kPlayerJoints, kRoomJoints, kPlayerBytes, kRoomBytes, kNameLength,
  kRoomProperties, kRoomPropertyBytes, kPropertyValueBytes,  // property writes
  kNone,  // within budget
};
inline constexpr size_t kBudgetKindCount = static_cast<size_t>(BudgetKind::kNone);
// snake_case label ("room_bodies", ...). Inline: the metrics exporter names its series.
inline std::string_view BudgetKindName(BudgetKind kind) {
  switch (kind) {
    case BudgetKind::kPlayerEntities: return "player_entities";
    case BudgetKind::kRoomEntities: return "room_entities";
    case BudgetKind::kPlayerBodies: return "player_bodies";
    case BudgetKind::kRoomBodies: return "room_bodies";
    case BudgetKind::kPlayerParticles: return "player_particles";
    case BudgetKind::kRoomParticles: return "room_particles";
    case BudgetKind::kPlayerJoints: return "player_joints";
    case BudgetKind::kRoomJoints: return "room_joints";
    case BudgetKind::kPlayerBytes: return "player_bytes";
    case BudgetKind::kRoomBytes: return "room_bytes";
    case BudgetKind::kNameLength: return "name_length";
    case BudgetKind::kRoomProperties: return "room_properties";
    case BudgetKind::kRoomPropertyBytes: return "room_property_bytes";
    case BudgetKind::kPropertyValueBytes: return "property_value_bytes";
    case BudgetKind::kNone: return "none";
  }
  return "none";
}

// What one entity costs.
struct EntityCost {
  uint32_t entities = 0;
  uint32_t bodies = 0;
  uint32_t particles = 0;
  uint32_t joints = 0;
  size_t bytes = 0;
  // A spawned container (`message_bytes`: its stored ControlMessage) with `physics` whether it
  // goes to PhyS.
  static EntityCost Of(const schema::Container& c, size_t message_bytes, bool physics);
  void Add(const EntityCost& o);
  void Subtract(const EntityCost& o);  // saturating at 0
};

class RoomLedger {
 public:
  RoomLedger(const RoomBudgets& budgets, uint32_t max_entities_per_player)
      : budgets_(budgets), max_entities_per_player_(max_entities_per_player) {}
  // The first budget that `cost` charged to `player` would exceed; kNone when it fits.
  // `name_bytes`: the container's name length.
  BudgetKind Check(uint32_t player, const EntityCost& cost, size_t name_bytes) const;
  void Charge(uint32_t player, const EntityCost& cost);
  void Refund(uint32_t player, const EntityCost& cost);  // forgets a player at zero
  // What `player` holds in the room (zero if nothing).
  EntityCost Of(uint32_t player) const;
  const EntityCost& total() const { return total_; }

 private:
  RoomBudgets budgets_;
  uint32_t max_entities_per_player_;
  std::unordered_map<uint32_t, EntityCost> by_player_;
  EntityCost total_;
};

}  // namespace edgephys
