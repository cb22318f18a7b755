// RoomHost::Ownership and the late joiner's ownership state (relay/room_host.h,
// docs/protocol.md "Ownership"): requests, hand overs, releases and takeover settings of an
// entity's owner, each change bumping the entity's authority sequence.
#include <flatbuffers/flatbuffers.h>

#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "relay/room_host.h"

namespace edgephys {
namespace {

void BuildOwnershipChanged(flatbuffers::FlatBufferBuilder& fbb, const Entity& e) {
  fbb.Clear();
  FinishControl(fbb, schema::CreateOwnershipChanged(fbb, e.id, e.owner, e.authority_seq,
                                                    e.former_owner, e.takeover_allowed));
}

// Rewrites the owner recorded in a stored ControlMessage{Spawn} (in place; same size), so a
// late joiner's Spawn names the current owner.
void SetSpawnOwner(std::vector<uint8_t>& spawn, uint32_t owner) {
  auto* msg = schema::GetMutableControlMessage(spawn.data());
  auto* container = static_cast<schema::Spawn*>(msg->mutable_body())->mutable_container();
  if (container != nullptr) container->mutate_owner(owner);
}

}  // namespace

void RoomHost::Ownership(MemberLink& link, const schema::OwnershipRequest& request, double now) {
  using schema::OwnershipAction;
  using schema::RejectReason;
  const uint32_t player = link.player_id();
  const uint32_t id = request.entity_id();
  const auto refuse = [&](RejectReason reason, std::string_view detail) {
    ++ownership_stats_.refused;
    link.SendError(reason, id, detail);
  };
  const RoomBudgets& budgets = room_.config().budgets;
  auto [rate, fresh] = ownership_rates_.try_emplace(player);
  if (fresh) {
    rate->second = TokenBucket(budgets.ownership_requests_per_s_per_player,
                               2 * budgets.ownership_requests_per_s_per_player);
  }
  if (!rate->second.Take(now)) {
    return refuse(RejectReason::RateLimited, "too many ownership requests from this player; slow down");
  }
  const OwnershipAction action = request.action();
  if (action > OwnershipAction::MAX) return refuse(RejectReason::InvalidMessage, "unknown ownership action");
  if ((link.permissions() & kPermissionSpawn) == 0) {
    return refuse(RejectReason::NotPermitted, "the join token does not allow owning entities");
  }
  Entity* e = room_.FindEntity(id);
  if (e == nullptr) return refuse(RejectReason::UnknownEntity, "no such entity");
  if (action == OwnershipAction::Request) {
    if (e->owner == player) {  // already granted: tell the requester again, nothing changes
      flatbuffers::FlatBufferBuilder fbb(64);
      BuildOwnershipChanged(fbb, *e);
      (void)link.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
      return;
    }
    if (e->physics == PhysicsRole::kSimulated) {
      return refuse(RejectReason::TakeoverRefused, "simulated by PhyS; grab it instead");
    }
    if (e->owner != 0 && !e->takeover_allowed) {
      return refuse(RejectReason::TakeoverRefused, "the owner does not allow takeover");
    }
    return ChangeOwner(*e, player);
  }
  if (e->owner != player) return refuse(RejectReason::NotOwner, "not your entity");
  switch (action) {
    case OwnershipAction::HandOver: {
      MemberLink* to = FindMember(request.to_player());
      if (request.to_player() == 0 || to == nullptr) {
        return refuse(RejectReason::UnknownPlayer, "no such player in the room");
      }
      if ((to->permissions() & kPermissionSpawn) == 0) {
        return refuse(RejectReason::NotPermitted, "that player's join token does not allow owning entities");
      }
      if (request.to_player() == player) return refuse(RejectReason::InvalidMessage, "already yours");
      return ChangeOwner(*e, request.to_player());
    }
    case OwnershipAction::Release: return ChangeOwner(*e, 0);
    case OwnershipAction::SetTakeover: {
      if (e->takeover_allowed == request.takeover_allowed()) return;
      e->takeover_allowed = request.takeover_allowed();
      flatbuffers::FlatBufferBuilder fbb(64);
      BuildOwnershipChanged(fbb, *e);
      BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, 0);
      return;
    }
    default: return;
  }
}

void RoomHost::ChangeOwner(Entity& e, uint32_t owner, uint32_t except_player) {
  e.former_owner = e.owner;
  e.owner = owner;
  ++e.authority_seq;
  SetSpawnOwner(e.spawn, owner);
  ++ownership_stats_.changes;
  RelayCounters::Inc(env_.counters->ownership_changes);
  flatbuffers::FlatBufferBuilder fbb(64);
  BuildOwnershipChanged(fbb, e);
  BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, except_player);
}

void RoomHost::SendJoinOwnership(uint32_t player_id) {
  auto member = room_.members().find(player_id);
  if (member == room_.members().end()) return;
  flatbuffers::FlatBufferBuilder fbb(64);
  for (const auto& [id, e] : room_.entities()) {
    if (e.authority_seq == 0 && !e.takeover_allowed) continue;
    BuildOwnershipChanged(fbb, e);
    SendToMember(player_id, member->second, {fbb.GetBufferPointer(), fbb.GetSize()});
  }
}

}  // namespace edgephys
