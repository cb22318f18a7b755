#include "relay/room_host.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "relay/entity_streams.h"

namespace edgephys {
namespace {

using schema::RejectReason;

// Whether clients want collision events of `e` (ReportContacts or Hand).
bool ReportsContacts(const Entity* e) {
  constexpr uint32_t kMask = static_cast<uint32_t>(schema::EntityFlags::ReportContacts) |
                             static_cast<uint32_t>(schema::EntityFlags::Hand);
  return e != nullptr && (e->flags & kMask) != 0;
}

// Scale of a spawned entity, every axis (docs/protocol.md, "Spawn rules").
constexpr float kMinScale = 1e-4f;
constexpr float kMaxScale = 1e4f;
bool ValidScale(const schema::Vec3& s) {
  for (float v : {s.x(), s.y(), s.z()}) {
    if (!std::isfinite(v) || v < kMinScale || v > kMaxScale) return false;
  }
  return true;
}

// States held per member for entities whose spawn has not arrived yet.
constexpr size_t kMaxEarlyStates = 1024;


// Rewrites the owner recorded in a stored ControlMessage{Spawn} (in place; same size).
void SetStoredOwner(std::vector<uint8_t>& spawn, uint32_t owner) {
  auto* msg = schema::GetMutableControlMessage(spawn.data());
  auto* container = static_cast<schema::Spawn*>(msg->mutable_body())->mutable_container();
  if (container != nullptr) container->mutate_owner(owner);
}

schema::PhysicsEventKind EventKindOf(physics::PhysicsEventType type) {
  using T = physics::PhysicsEventType;
  using K = schema::PhysicsEventKind;
  switch (type) {
    case T::kCollisionEnter: return K::CollisionEnter;
    case T::kCollisionExit: return K::CollisionExit;
    case T::kTriggerEnter: return K::TriggerEnter;
    case T::kTriggerExit: return K::TriggerExit;
    case T::kGuardReset: return K::GuardReset;
  }
  return K::CollisionEnter;
}

}  // namespace

RoomHost::RoomHost(std::string name, const RoomConfig& config, const RoomHostEnv& env,
                   double now)
    : room_(std::move(name), config, now), env_(env) {
  batch_.states.reserve(kMaxPacketSize / 8);
}

bool RoomHost::IdleExpired(double now) const {
  return room_.empty() && now - room_.empty_since() >= room_.config().idle_ttl_s;
}

MemberLink* RoomHost::FindMember(uint32_t player_id) const {
  auto it = room_.members().find(player_id);
  return it == room_.members().end() ? nullptr : it->second.link;
}

// --- Membership ------------------------------------------------------------------------------

bool RoomHost::Join(MemberLink& link, double now) {
  (void)now;
  uint32_t slot = room_.AddMember(link.player_id(), &link);
  if (slot == 0) {
    link.SendError(RejectReason::RoomFull, 0, "room is full");
    return false;
  }
  SendJoinState(link, slot);
  SendJoinProperties(link.player_id());
  SendJoinOwnership(link.player_id());
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreatePlayerJoined(fbb, link.player_id()));
  BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, link.player_id());
  spdlog::info("player {} joined room '{}' (slot {}, {} players)", link.player_id(), name(), slot,
               room_.size());
  return true;
}

uint8_t RoomHost::state_format() const { return StateFormatOf(room_.config().replication); }

void RoomHost::SendJoinState(MemberLink& link, uint32_t slot) {
  const ReplicationConfig& rc = room_.config().replication;
  const QuantizationConfig q = QuantizationOf(rc);
  flatbuffers::FlatBufferBuilder fbb(256);
  {
    schema::Vec3 bmin(q.bounds_min.x, q.bounds_min.y, q.bounds_min.z);
    schema::Vec3 bmax(q.bounds_max.x, q.bounds_max.y, q.bounds_max.z);
    auto name_offset = fbb.CreateString(name());
    schema::JoinedBuilder jb(fbb);
    jb.add_room(name_offset);
    jb.add_player_id(link.player_id());
    jb.add_entity_id_base(slot * kEntityIdBlock);
    jb.add_tick_rate_hz(static_cast<uint16_t>(room_.config().tick_rate_hz));
    jb.add_state_format(state_format());
    jb.add_position_step_m(q.position_step_m);
    jb.add_rotation_bound_deg(q.rotation_error_deg);
    jb.add_bounds_min(&bmin);
    jb.add_bounds_max(&bmax);
    FinishControl(fbb, jb.Finish());
  }
  (void)link.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
  // States only once Joined is acknowledged (a state before it could not be decoded).
  link.StartReplication(rc);
  std::vector<uint32_t> players;
  for (const auto& [id, m] : room_.members()) players.push_back(id);
  fbb.Clear();
  FinishControl(fbb, schema::CreateRoomState(fbb, fbb.CreateString(name()),
                                             fbb.CreateVector(players),
                                             static_cast<uint32_t>(room_.entities().size())));
  if (!link.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()})) return;
  if (room_.entities().empty()) return;
  join_streams_.insert_or_assign(link.player_id(), JoinStream(room_.entities()));
  PumpJoinStreams(link.player_id());
}

void RoomHost::PumpJoinStreams(uint32_t only) {
  for (auto it = join_streams_.begin(); it != join_streams_.end();) {
    if (only != 0 && it->first != only) {
      ++it;
      continue;
    }
    MemberLink* link = FindMember(it->first);
    // Erased when the member is gone, finished, or overflowed (the link disconnected it).
    if (link == nullptr || !it->second.Pump(*link, room_.entities()) || it->second.done()) {
      it = join_streams_.erase(it);
    } else {
      ++it;
    }
  }
}

void RoomHost::Leave(MemberLink& link, double now) {
  const auto it = room_.members().find(link.player_id());
  if (it == room_.members().end() || it->second.link != &link) return;
  join_streams_.erase(link.player_id());
  // Its entities go to the room, to PhyS (ownership changes the others are told of, so the
  // leaver's late states count as stale) or, below, away (LeaveChoiceOf).
  HandOffLeaversEntities(link.player_id(), now);
  std::vector<uint32_t> despawned;
  room_.RemoveMember(link.player_id(), &despawned);
  env_.counters->entities.fetch_sub(static_cast<int64_t>(despawned.size()),
                                    std::memory_order_relaxed);
  // As in Despawn: the members who stay drop what they held of the despawned entities (views,
  // encoder baselines), or it would pile up for as long as they stay, and a later entity
  // reusing an id would be delta-coded against a baseline their client has dropped.
  for (const auto& [pid, m] : room_.members()) {
    for (uint32_t id : despawned) m.link->Forget(id);
  }
  for (uint32_t id : despawned) {
    properties_.EraseEntity(id);  // receivers drop an entity's properties with its Despawn
    BroadcastDespawn(id, 0);
  }
  // Entities the room took over: their stored spawn now names the room as owner.
  for (const auto& [id, e] : room_.entities()) {
    if (e.owner == 0) SetStoredOwner(const_cast<std::vector<uint8_t>&>(e.spawn), 0);
  }
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreatePlayerLeft(fbb, link.player_id()));
  BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, 0);
  if (room_.empty()) room_.set_empty_since(now);
  spdlog::info("player {} left room '{}'", link.player_id(), name());
}

// --- Requests --------------------------------------------------------------------------------

void RoomHost::Spawn(MemberLink& link, std::span<const uint8_t> message,
                     const schema::Spawn& spawn, double now) {
  const schema::Container* c = spawn.container();
  if (c == nullptr || c->transform() == nullptr) {
    return link.SendError(RejectReason::InvalidMessage, 0, "spawn without container/transform");
  }
  const uint32_t id = c->entity_id();
  const uint32_t player = link.player_id();
  if (message.size() > env_.limits->max_spawn_bytes) {
    return link.SendError(RejectReason::InvalidContainer, id,
                          "container larger than the relay allows");
  }
  if (!link.AllowSpawn(now)) {
    return link.SendError(RejectReason::RateLimited, id, "too many spawns; slow down");
  }
  if ((link.permissions() & kPermissionSpawn) == 0) {
    return link.SendError(RejectReason::NotOwner, id, "the join token does not allow spawning");
  }
  Member* member = room_.FindMember(player);
  if (member == nullptr) return link.SendError(RejectReason::NotJoined, id, "not a member");
  if (id / kEntityIdBlock != member->slot) {
    return link.SendError(RejectReason::NotOwner, id, "entity id outside your id block");
  }
  if (c->owner() != player) {
    return link.SendError(RejectReason::NotOwner, id, "container owner must be the sender");
  }
  if (room_.FindEntity(id) != nullptr) {
    return link.SendError(RejectReason::DuplicateEntity, id, "entity id already in use");
  }
  const schema::Transform* t = c->transform();
  Entity e;
  e.id = id;
  e.owner = player;
  e.flags = c->flags();
  if (c->on_owner_leave() > schema::OwnerLeave::MAX) {
    return link.SendError(RejectReason::InvalidMessage, id, "unknown on_owner_leave value");
  }
  e.on_owner_leave = static_cast<uint8_t>(c->on_owner_leave());
  e.state.entity_id = id;
  e.state.position = {t->position().x(), t->position().y(), t->position().z()};
  e.state.rotation = {t->rotation().x(), t->rotation().y(), t->rotation().z(), t->rotation().w()};
  if (!IsValidState(e.state)) {
    return link.SendError(RejectReason::InvalidMessage, id, "transform not finite or not unit");
  }
  if (!ValidScale(t->scale())) {
    return link.SendError(RejectReason::InvalidMessage, id,
                          "scale must be finite and within [1e-4, 1e4] on every axis");
  }
  if (c->parent_id() != 0) {
    // The parent must exist already, and not descend from this id in any member's view
    // (Room::ParentWouldCycle: a despawned parent's id coming back as its old child's child).
    if (c->parent_id() == id || room_.FindEntity(c->parent_id()) == nullptr) {
      return link.SendError(RejectReason::UnknownEntity, id, "unknown parent (or itself)");
    }
    if (room_.ParentWouldCycle(id, c->parent_id())) {
      return link.SendError(RejectReason::InvalidMessage, id,
                            "parent would form a cycle (a member still shows this id as an "
                            "ancestor of that parent)");
    }
  }
  e.physics = RoomPhysics::RoleOf(*c);
  if (e.physics != PhysicsRole::kNone && !room_.config().physics) {
    return link.SendError(RejectReason::InvalidContainer, id, "physics is off in this room");
  }
  e.cost = EntityCost::Of(*c, message.size(), e.physics != PhysicsRole::kNone);
  const size_t name_bytes = c->name() == nullptr ? 0 : c->name()->size();
  if (const BudgetKind over = room_.ledger().Check(player, e.cost, name_bytes);
      over != BudgetKind::kNone) {
    env_.counters->RefuseOverBudget(over);
    return link.SendError(over == BudgetKind::kPlayerEntities ? RejectReason::EntityLimit
                                                              : RejectReason::OverBudget,
                          id, std::string("over budget: ") + std::string(BudgetKindName(over)));
  }
  e.parent = c->parent_id();
  e.changed_at = now;
  e.state_time = now;
  e.creator = player;
  e.spawn_seq = room_.NextSpawnSeq();
  if (e.physics != PhysicsRole::kNone) {
    if (room_.physics() == nullptr) room_.set_physics(env_.placement->Place(0, now));
    Status added = room_.physics()->Add(*c, e.physics);
    if (!added.ok()) return link.SendError(RejectReason::InvalidContainer, id, added.reason());
    if (e.physics == PhysicsRole::kSimulated) e.owner = 0;  // PhyS is the authority now
  }
  if (auto early = member->early_states.find(id); early != member->early_states.end()) {
    e.state = early->second;  // a state overtook the spawn
    e.version = 2;
    member->early_states.erase(early);
  }
  e.spawn.assign(message.begin(), message.end());
  const bool simulated = e.physics == PhysicsRole::kSimulated;
  // The stored spawn tells every client (the creator included) that PhyS owns it.
  if (simulated) SetStoredOwner(e.spawn, 0);
  Entity& added = room_.AddEntity(std::move(e));
  env_.counters->entities.fetch_add(1, std::memory_order_relaxed);
  BroadcastReliable(added.spawn, simulated ? 0 : player);
}

void RoomHost::Despawn(MemberLink& link, uint32_t entity_id) {
  const uint32_t player = link.player_id();
  Entity* e = room_.FindEntity(entity_id);
  if (e == nullptr) return link.SendError(RejectReason::UnknownEntity, entity_id, "no such entity");
  if (e->owner != player && !(e->owner == 0 && e->creator == player)) {
    return link.SendError(RejectReason::NotOwner, entity_id, "not your entity");
  }
  const bool simulated = e->physics == PhysicsRole::kSimulated;
  room_.RemoveEntity(entity_id);
  properties_.EraseEntity(entity_id);
  env_.counters->entities.fetch_sub(1, std::memory_order_relaxed);
  for (const auto& [pid, m] : room_.members()) m.link->Forget(entity_id);
  BroadcastDespawn(entity_id, simulated ? 0 : player);
}

void RoomHost::Grab(MemberLink& link, uint32_t entity_id, uint32_t hand_id) {
  Entity* e = GrabTarget(link, entity_id, hand_id);
  if (e == nullptr) return;
  e->grab_requester = link.player_id();
  room_.physics()->RequestGrab(entity_id, hand_id);  // answered in ApplyPhysics
}

void RoomHost::Release(MemberLink& link, uint32_t entity_id, double now) {
  Entity* e = room_.FindEntity(entity_id);
  if (e == nullptr) return link.SendError(RejectReason::UnknownEntity, entity_id, "no such entity");
  Entity* hand = e->held_by != 0 ? room_.FindEntity(e->held_by) : nullptr;
  if (hand == nullptr || hand->owner != link.player_id()) {
    return link.SendError(RejectReason::NotOwner, entity_id, "not held by your hand");
  }
  const uint32_t hand_id = e->held_by;
  if (room_.physics() != nullptr) room_.physics()->Release(entity_id);
  e->held_by = 0;
  BroadcastPhysicsEvent(schema::PhysicsEventKind::Released, entity_id, hand_id, now);
}

void RoomHost::ApplyStates(MemberLink& link, std::span<const uint8_t> payload, double now) {
  if (!DecodeStateBatch(payload, &batch_).ok()) return link.DropPayload(DropReason::kMalformed);
  const uint32_t player = link.player_id();
  Member* member = room_.FindMember(player);
  for (const EntityState& st : batch_.states) {
    Entity* e = room_.FindEntity(st.entity_id);
    DropReason reject = DropReason::kCount;
    if (e == nullptr) {
      if (member != nullptr && st.entity_id / kEntityIdBlock == member->slot && IsValidState(st) &&
          (member->early_states.size() < kMaxEarlyStates ||
           member->early_states.count(st.entity_id))) {
        member->early_states[st.entity_id] = st;  // its spawn is still on the way
        continue;
      }
      reject = DropReason::kUnknownEntity;
    } else if (e->owner != player) {
      reject = DropReason::kNotOwner;
      if (e->former_owner == player && e->authority_seq != 0) {
        ++ownership_stats_.stale;
        RelayCounters::Inc(env_.counters->stale_owner_states);
      }
    } else if (!IsValidState(st)) {
      reject = DropReason::kInvalidValue;
    }
    if (reject != DropReason::kCount) {
      link.DropUpdate(reject);
      continue;
    }
    if (e->physics == PhysicsRole::kMirrored) TrackOwnerMotion(*e, st, now);
    e->state = st;
    ++e->version;
    e->changed_at = now;
    e->state_time = now;
    if (e->physics == PhysicsRole::kMirrored && room_.physics() != nullptr) {
      room_.physics()->Drive(st.entity_id, st, now);
    }
    RelayCounters::Inc(env_.counters->entity_updates_received);
  }
}

// --- PhyS ------------------------------------------------------------------------------------

PhysicsLink* RoomHost::PreparePhysics(double now) {
  if (room_.physics() == nullptr) return nullptr;
  if (!room_.physics()->Healthy(now)) FailOver(now);
  return room_.physics();
}

uint32_t RoomHost::physics_worker() const {
  return room_.physics() == nullptr ? 0 : room_.physics()->worker();
}

void RoomHost::ApplyPhysics(const PhysicsLink::StepOutput& out, double now) {
  RelayCounters& counters = *env_.counters;
  if (out.steps > 0 && room_.physics()->worker() == 0) {
    counters.physics_step_seconds.Observe(out.step_seconds / out.steps);
    RelayCounters::Inc(counters.physics_steps, static_cast<uint64_t>(out.steps));
  }
  // The time the states hold, not their arrival: an asynchronous world's steps arrive a step's
  // computation late and unevenly, and several steps may arrive in one output.
  const double state_time = out.state_time >= 0 ? std::min(out.state_time, now) : now;
  for (const RoomPhysics::MovedBody& m : out.moved) {
    Entity* e = room_.FindEntity(m.state.entity_id);
    if (e == nullptr || e->physics != PhysicsRole::kSimulated || !IsValidState(m.state)) continue;
    e->state = m.state;
    e->state_time = state_time;
    e->linear_velocity = m.linear;
    e->angular_velocity = m.angular;
    ++e->version;
    e->changed_at = now;
  }
  for (const RoomPhysics::SoftNodes& part : out.soft) {
    Entity* e = room_.FindEntity(part.id);
    if (e == nullptr || part.total == 0 || part.first + part.nodes.size() > part.total) continue;
    e->nodes.resize(part.total);
    std::copy(part.nodes.begin(), part.nodes.end(), e->nodes.begin() + part.first);
    ++e->nodes_version;
    if (e->nodes_restored) {  // the new world's first particles after a failover
      e->nodes_restored = false;
      e->nodes_resumed_at = now;
      e->resumed_version = e->nodes_version;
      e->resumed_nodes = e->nodes;
    } else if (!e->resumed_nodes.empty() && now - e->nodes_resumed_at > Entity::kResumeWindowS) {
      e->resumed_nodes = {};
    }
  }
  IssuePosedGrabs(out.steps);
  for (const RoomPhysics::GrabResult& g : out.grabs) {
    Entity* e = room_.FindEntity(g.entity);
    if (e == nullptr) continue;
    const uint32_t requester = e->grab_requester;
    e->grab_requester = 0;
    if (g.ok) {
      e->held_by = g.hand;
      BroadcastPhysicsEvent(schema::PhysicsEventKind::Grabbed, g.entity, g.hand, now);
    } else if (MemberLink* m = FindMember(requester)) {
      m->SendError(RejectReason::GrabRefused, g.entity, g.detail);
    }
  }
  for (const physics::PhysicsEvent& ev : out.events) {
    using T = physics::PhysicsEventType;
    if ((ev.type == T::kCollisionEnter || ev.type == T::kCollisionExit) &&
        !ReportsContacts(room_.FindEntity(ev.entity_a)) &&
        !ReportsContacts(room_.FindEntity(ev.entity_b))) {
      continue;  // a contact nobody asked about (a pile of boxes) stays inside PhyS
    }
    if (ev.type == T::kGuardReset) RelayCounters::Inc(counters.guard_resets);
    BroadcastPhysicsEvent(EventKindOf(ev.type), ev.entity_a, ev.entity_b, now);
  }
}

size_t RoomHost::Restore(std::vector<Entity> entities, const std::map<uint32_t, uint32_t>& slots,
                         double now) {
  for (const auto& [player, slot] : slots) room_.ReserveSlot(player, slot);
  size_t skipped = 0;
  bool physics = false;
  for (Entity& e : entities) {
    const auto* msg = VerifyControlMessage(e.spawn, schema::Body::Spawn);
    const schema::Container* c = msg != nullptr ? msg->body_as_Spawn()->container() : nullptr;
    if (c == nullptr || c->entity_id() != e.id || c->transform() == nullptr ||
        room_.FindEntity(e.id) != nullptr || !IsValidState(e.state)) {
      ++skipped;
      continue;
    }
    physics = physics || e.physics != PhysicsRole::kNone;
    // Charged to its creator again, as when it was spawned (budgets survive a failover).
    e.cost = EntityCost::Of(*c, e.spawn.size(), e.physics != PhysicsRole::kNone);
    room_.AdvanceSpawnSeq(e.spawn_seq);
    e.changed_at = now;
    e.state_time = now;
    room_.AddEntity(std::move(e));
    env_.counters->entities.fetch_add(1, std::memory_order_relaxed);
  }
  if (physics) FailOver(now);
  return skipped;
}

void RoomHost::FailOver(double now) {
  std::unique_ptr<PhysicsLink> old = room_.TakePhysics();
  const uint32_t dead_worker = old ? old->worker() : 0;
  if (old) old->Detach();  // it failed: no goodbye to a dead or stalled worker
  old.reset();
  room_.set_physics(env_.placement->Place(dead_worker, now));
  PhysicsLink& link = *room_.physics();
  std::vector<Entity*> order;
  for (const auto& [id, e] : room_.entities()) {
    if (e.physics != PhysicsRole::kNone) order.push_back(room_.FindEntity(id));
  }
  std::sort(order.begin(), order.end(),
            [](const Entity* a, const Entity* b) { return a->spawn_seq < b->spawn_seq; });
  for (Entity* e : order) {
    e->touching = 0;  // the new world reports its overlaps afresh
    const auto* msg = schema::GetControlMessage(e->spawn.data());
    const schema::Container* c = msg->body_as_Spawn()->container();
    Status added = link.Add(*c, e->physics);
    if (!added.ok()) {
      spdlog::error("failover of room '{}': entity {} not restored: {}", name(), e->id,
                    added.ToString());
      continue;
    }
    if (e->physics == PhysicsRole::kSimulated && !e->nodes.empty()) {
      // A soft body restarts from the deformed particles the relay last received, not from
      // its spawn shape (they are what every receiver shows).
      link.RestoreSoftBody(e->id, e->nodes);
      e->nodes_restored = true;
    } else if (e->physics == PhysicsRole::kSimulated) {
      link.Restore(e->id, e->state, e->linear_velocity, e->angular_velocity);
    } else {
      // A mirrored body is teleported to where its owner last put it: driven from its spawn
      // pose instead, a kinematic body would sweep the room in one step and slam whatever it
      // met (a plate pressing a soft body pushed it through the floor).
      link.Restore(e->id, e->state, {}, {});
      link.Drive(e->id, e->state, e->state_time);
    }
  }
  for (Entity* e : order) {
    if (e->held_by != 0) link.RequestGrab(e->id, e->held_by, /*force=*/true);
  }
  RelayCounters::Inc(env_.counters->physics_failovers);
  spdlog::warn("PhyS for room '{}' failed over from {} to {} ({} entities)", name(),
               dead_worker ? "a worker" : "embedded", link.worker() ? "another worker" : "embedded",
               order.size());
}

// --- Fan-out ---------------------------------------------------------------------------------

void RoomHost::BeginTick(double now, std::vector<MemberLink*>* receivers) {
  if (!join_streams_.empty()) PumpJoinStreams();
  room_.PrepareStates(now);  // once per changed entity, not once per receiver
  room_.BuildFrame();        // once per room tick, not once per receiver
  for (const auto& [pid, member] : room_.members()) {
    if (member.link->ReadyForStates()) receivers->push_back(member.link);
  }
  room_.ScheduleNextTick(now);
}

void RoomHost::BroadcastReliable(std::span<const uint8_t> message, uint32_t except_player) {
  for (const auto& [pid, m] : room_.members()) {
    if (pid != except_player) SendToMember(pid, m, message);
  }
}

void RoomHost::SendToMember(uint32_t player_id, const Member& member,
                            std::span<const uint8_t> message) {
  if (auto stream = join_streams_.find(player_id); stream != join_streams_.end()) {
    // After the room's existing state; a joiner that falls a whole queue behind is dropped
    // as its queue would have overflowed.
    if (!stream->second.Hold(message, member.link->ReliableCapacity())) {
      join_streams_.erase(stream);
      member.link->Overflow();
    }
  } else {
    (void)member.link->SendReliable(message);
  }
}

void RoomHost::BroadcastDespawn(uint32_t entity_id, uint32_t except_player) {
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateDespawn(fbb, entity_id));
  BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, except_player);
}

void RoomHost::BroadcastPhysicsEvent(schema::PhysicsEventKind kind, uint32_t a, uint32_t b,
                                     double now) {
  // Whatever an event names is being interacted with: replication takes it out of the
  // ambient class while a touch is open (Enter without Exit) and for
  // ReplicationConfig::interaction_linger_s after any event.
  using K = schema::PhysicsEventKind;
  const bool enter = kind == K::CollisionEnter || kind == K::TriggerEnter;
  const bool exit = kind == K::CollisionExit || kind == K::TriggerExit;
  for (uint32_t id : {a, b}) {
    Entity* e = id != 0 ? room_.FindEntity(id) : nullptr;
    if (e == nullptr) continue;
    e->interacted_at = now;
    if (enter) ++e->touching;
    if (exit && e->touching > 0) --e->touching;
  }
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreatePhysicsEvent(fbb, kind, a, b));
  BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, 0);
}

}  // namespace edgephys
