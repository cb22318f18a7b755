#include "relay/room.h"

#include <algorithm>
#include <cstring>

#include "relay/replication.h"
#include "edgephys/schema/control_generated.h"

namespace edgephys {

Room::Room(std::string name, const RoomConfig& config, double now)
    : name_(std::move(name)),
      config_(config),
      ledger_(config.budgets, config.max_entities_per_player),
      next_tick_(now),
      empty_since_(now) {}

uint32_t Room::AddMember(uint32_t player_id, MemberLink* link) {
  if (members_.size() >= config_.capacity) return 0;
  if (auto r = reserved_slots_.find(player_id); r != reserved_slots_.end()) {
    const uint32_t slot = r->second;
    bool taken = false;
    for (const auto& [id, m] : members_) taken = taken || m.slot == slot;
    if (!taken) {
      members_[player_id] = Member{player_id, slot, link, {}};
      return slot;
    }
  }
  // Lowest free slot: not a member's, and not the id block of entities that outlived their
  // owner (Persistent ones pass to the room but keep their ids). Slot 0 is the room's own.
  std::vector<bool> used(kEntityIdBlock, false);
  used[0] = true;
  for (const auto& [id, m] : members_) used[m.slot] = true;
  for (const auto& [id, slot] : reserved_slots_) used[slot] = true;
  for (const auto& [id, e] : entities_) used[id / kEntityIdBlock] = true;
  uint32_t slot = 1;
  while (slot < kEntityIdBlock && used[slot]) ++slot;
  if (slot >= kEntityIdBlock) return 0;
  members_[player_id] = Member{player_id, slot, link, {}};
  return slot;
}

void Room::RemoveMember(uint32_t player_id, std::vector<uint32_t>* despawned) {
  if (members_.erase(player_id) == 0) return;
  const size_t first = despawned->size();
  for (auto& [id, e] : entities_) {
    if (e.owner != player_id && !(e.owner == 0 && e.creator == player_id)) continue;
    // Released to the room by an ownership change (offloaded to PhyS or not): the room's,
    // whoever leaves.
    if (e.owner == 0 && e.authority_seq != 0) continue;
    if (LeaveChoiceOf(e) != kOwnerLeaveDespawn) {
      e.owner = 0;  // the room's now; still charged to its creator
    } else {
      despawned->push_back(id);
    }
  }
  for (size_t i = first; i < despawned->size(); ++i) RemoveEntity((*despawned)[i]);
}

Member* Room::FindMember(uint32_t player_id) {
  auto it = members_.find(player_id);
  return it == members_.end() ? nullptr : &it->second;
}

Entity* Room::FindEntity(uint32_t id) {
  auto it = entities_.find(id);
  return it == entities_.end() ? nullptr : &it->second;
}

Entity& Room::AddEntity(Entity entity) {
  uint32_t id = entity.id;
  if (auto old = entities_.find(id); old != entities_.end()) ReleaseSlot(old->second);
  ledger_.Charge(entity.creator, entity.cost);
  if (Entity* parent = entity.parent != 0 ? FindEntity(entity.parent) : nullptr) {
    ++parent->children;
  }
  if (free_slots_.empty()) {
    entity.slot = static_cast<uint32_t>(slots_.size());
    slots_.push_back(nullptr);
  } else {
    entity.slot = free_slots_.back();
    free_slots_.pop_back();
  }
  if (++serials_ == 0) ++serials_;
  entity.serial = serials_;
  entity.shared.reset();  // a copy's: this occupancy gets its own (PrepareStates)
  Entity& e = entities_[id] = std::move(entity);
  slots_[e.slot] = &e;
  frame_stale_ = true;
  return e;
}

void Room::ReleaseSlot(const Entity& e) {
  if (e.slot < slots_.size() && slots_[e.slot] == &e) {
    slots_[e.slot] = nullptr;
    free_slots_.push_back(e.slot);
  }
}

void Room::RemoveEntity(uint32_t id) {
  auto it = entities_.find(id);
  if (it == entities_.end()) return;
  const Entity& e = it->second;
  ledger_.Refund(e.creator, e.cost);
  if (Entity* parent = e.parent != 0 ? FindEntity(e.parent) : nullptr) {
    if (parent->children > 0) --parent->children;
  }
  const bool had_children = e.children != 0;
  ReleaseSlot(e);
  frame_stale_ = true;
  entities_.erase(it);
  if (physics_) physics_->Remove(id);
  if (!had_children) return;
  // Its children become roots (as in PhyS), also in the spawn a late joiner is sent, so an
  // entity that later reuses the id is never anyone's ancestor: no parent cycle can form.
  for (auto& [cid, child] : entities_) {
    if (child.parent != id) continue;
    child.parent = 0;
    child.former_parent = id;
    auto* msg = schema::GetMutableControlMessage(child.spawn.data());
    auto* spawn = static_cast<schema::Spawn*>(msg->mutable_body());
    if (auto* c = spawn->mutable_container()) c->mutate_parent_id(0);
  }
}

bool Room::ParentWouldCycle(uint32_t id, uint32_t parent) const {
  // An entity has one upward link at most (its parent, or once that went, its former parent:
  // a parent is never set again), and a spawn that would close a cycle is refused here, so
  // the walk is a chain of at most entities_.size() steps; the bound is a guard.
  std::vector<uint32_t> pending{parent};
  size_t steps = 0;
  while (!pending.empty() && steps++ <= entities_.size()) {
    const uint32_t at = pending.back();
    pending.pop_back();
    if (at == id) return true;
    auto it = entities_.find(at);
    if (it == entities_.end()) continue;
    if (it->second.parent != 0) pending.push_back(it->second.parent);
    if (it->second.former_parent != 0) pending.push_back(it->second.former_parent);
  }
  return !pending.empty();  // the guard tripped: refuse rather than risk a cycle
}

void Room::BuildFrame() {
  constexpr uint32_t kFlagHand = 1u << 4;  // schema::EntityFlags::Hand
  frame_.hands.clear();
  if (frame_stale_) {  // ids sorted once per change of the set, not per receiver per tick
    frame_stale_ = false;
    frame_.by_id.clear();
    for (const Entity* e : slots_) {
      if (e != nullptr) frame_.by_id.push_back(e);
    }
    std::sort(frame_.by_id.begin(), frame_.by_id.end(),
              [](const Entity* a, const Entity* b) { return a->id < b->id; });
  }
  // Whether an entity is a soft body can change (its first particles), so this part is redone
  // every tick; it costs one pass over the room's entities, shared by all receivers.
  frame_.soft.clear();
  for (const Entity* e : frame_.by_id) {
    if (e->flags & kFlagHand) frame_.hands.push_back(e->state.position);
    if (e->nodes_version != 0 && !e->nodes.empty()) frame_.soft.push_back(e);
  }
}

void Room::ScheduleNextTick(double now) {
  double interval = 1.0 / std::max(1.0, config_.tick_rate_hz);
  next_tick_ += interval;
  if (next_tick_ < now) next_tick_ = now + interval;  // fell behind: skip, don't burst
}

void Room::PrepareStates(double now) {
  if (config_.replication.plugin != nullptr) return;  // a plug-in encodes per receiver
  if (!quantization_tried_) {
    quantization_tried_ = true;
    auto params = MakeQuantizationParams(QuantizationOf(config_.replication));
    if (params.ok()) quantization_ = *params;
    if (params.ok() && UsesSharedEncoding(config_.replication)) {
      shared_ = std::make_unique<SharedDeltaRoom>(
          *params, SharedVersionWindowFor(config_.tick_rate_hz));
    }
  }
  if (!quantization_) return;
  if (shared_) shared_->BeginTick(static_cast<uint32_t>(static_cast<uint64_t>(now * 1000.0)));
  for (auto& [id, e] : entities_) {
    if (!e.prepared_valid ||
        std::memcmp(&e.prepared_of.position, &e.state.position, sizeof(Vec3f)) != 0 ||
        std::memcmp(&e.prepared_of.rotation, &e.state.rotation, sizeof(Quatf)) != 0) {
      e.prepared = PrepareState(*quantization_, e.state);
      e.prepared_of = e.state;
      e.prepared_valid = true;
    }
    if (shared_) {
      if (!e.shared) {
        e.shared = std::make_shared<SharedEntity>();
        e.shared->BindSlot(e.slot, e.serial);
      }
      shared_->PrepareEntity(*e.shared, e.prepared);
    }
  }
}

}  // namespace edgephys
