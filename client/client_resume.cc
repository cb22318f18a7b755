// The client's side of a relay failover that concerns its entities: after a resume, the spawns
// of the owned entities the restored room may lack are sent again, and an entity the relay
// will not take back is reported to the game as lost (docs/protocol.md, "Failover and
// resume"). The handshake side of a resume (StartResume, the relay candidates) is in client.cc.
#include <algorithm>
#include <string>

#include "client/client_impl.h"

namespace edgephys {
namespace {

// How long after the relay acknowledged the re-spawns their refusals may still arrive (a lost
// Error is resent; 4 round trips if that is longer).
constexpr double kRespawnAnswerS = 1.0;

// Error reasons a relay answers a Spawn with (relay/room_host.cc RoomHost::Spawn). Any other
// Error naming a re-spawned entity answers something else and reaches the game unchanged.
bool IsSpawnRefusal(schema::RejectReason r) {
  using R = schema::RejectReason;
  switch (r) {
    case R::DuplicateEntity:
    case R::EntityLimit:
    case R::OverBudget:
    case R::RateLimited:
    case R::NotOwner:
    case R::NotJoined:
    case R::NotPermitted:
    case R::UnknownEntity:
    case R::InvalidMessage:
    case R::InvalidContainer:
      return true;
    default:
      return false;
  }
}

}  // namespace

void Client::Impl::RespawnAfterResume() {
  std::vector<uint32_t> ids;
  for (const auto& [id, e] : owned_) {
    if (!e.spawn.empty() && id - entity_id_base_ < kEntityIdBlock) ids.push_back(id);
  }
  // Id order is spawn order within the block, so a parent goes before its children.
  std::sort(ids.begin(), ids.end());
  for (uint32_t id : ids) {
    OwnedEntity& e = owned_[id];
    // At its current pose (the stored message is patched in place: same size).
    auto* msg = schema::GetMutableControlMessage(e.spawn.data());
    auto* container = static_cast<schema::Spawn*>(msg->mutable_body())->mutable_container();
    if (container != nullptr && container->transform() != nullptr) {
      auto* t = container->mutable_transform();
      const EntityState& s = e.state;
      t->mutable_position() = schema::Vec3(s.position.x, s.position.y, s.position.z);
      t->mutable_rotation() = schema::Quat(s.rotation.x, s.rotation.y, s.rotation.z, s.rotation.w);
    }
    Status sent = connection_->SendReliable(e.spawn);
    if (!sent.ok()) {
      // The reliable queue is full: this spawn can never reach the relay.
      ReportLost(static_cast<uint16_t>(schema::RejectReason::RateLimited), id,
                 "the re-spawn could not be queued (" + std::string(sent.reason()) + ")");
      continue;
    }
    respawned_.insert(id);
    ++respawns_sent_;
  }
  respawn_end_ = connection_->reliable_queued_end();
  respawn_answers_by_ = 0;
}

void Client::Impl::ExpireRespawns(double now) {
  if (respawn_answers_by_ == 0 && connection_->reliable_acked_end() >= respawn_end_) {
    respawn_answers_by_ = now + std::max(kRespawnAnswerS, 4 * connection_->stats().rtt_s);
  }
  if (respawn_answers_by_ > 0 && now >= respawn_answers_by_) respawned_.clear();
}

bool Client::Impl::RespawnRefused(uint16_t reason, uint32_t entity_id, std::string_view detail) {
  auto it = respawned_.find(entity_id);
  if (it == respawned_.end()) return false;
  const auto r = static_cast<schema::RejectReason>(reason);
  if (!IsSpawnRefusal(r)) return false;
  respawned_.erase(it);
  if (r == schema::RejectReason::DuplicateEntity) {
    ++respawns_duplicate_;  // the restored room holds it already
    return true;
  }
  ReportLost(reason, entity_id, std::string("the relay refused its re-spawn: ") + std::string(detail));
  return true;
}

void Client::Impl::ReportLost(uint16_t reason, uint32_t id, std::string_view why) {
  if (owned_.erase(id) == 0) return;
  tracker_.Forget(id);
  ForgetEntityProperties(id);
  ++entities_lost_;
  listener_->OnError(reason, id, std::string("lost in failover: ") + std::string(why));
}

}  // namespace edgephys
