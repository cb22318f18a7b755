// RoomHost::SetProperty and the late joiner's and failover's properties (relay/room_host.h,
// docs/protocol.md "Properties").
#include <flatbuffers/flatbuffers.h>

#include <string>

#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/property_codec.h"
#include "relay/room_host.h"

namespace edgephys {
namespace {

// Whether `player` owns entity `e` for its Owner-authority properties: its owner, or the
// creator of an entity the room or PhyS owns (as for Despawn).
bool OwnsEntity(const Entity& e, uint32_t player) {
  return e.owner == player || (e.owner == 0 && e.creator == player);
}

}  // namespace

void RoomHost::SetProperty(MemberLink& link, const schema::PropertySet& set, double now) {
  using schema::RejectReason;
  const uint32_t player = link.player_id();
  const uint32_t entity_id = set.entity_id();
  const std::string_view key = set.key() != nullptr ? set.key()->string_view() : std::string_view();
  // Every refusal names the property (its key, cut short) so a writer can tell its writes apart.
  const auto refuse = [&](RejectReason reason, std::string_view why) {
    ++property_stats_.refused;
    std::string detail(why);
    if (!key.empty() && key.size() <= kMaxPropertyKeyBytes) {
      detail += " (property '" + std::string(key) + "')";
    }
    link.SendError(reason, entity_id, detail);
  };
  if ((link.permissions() & kPermissionProperty) == 0) {
    return refuse(RejectReason::NotPermitted, "the join token does not allow writing properties");
  }
  const RoomBudgets& budgets = room_.config().budgets;
  if (!TakeKeyedToken(property_rates_, player, budgets.property_writes_per_s_per_player, now)) {
    return refuse(RejectReason::RateLimited, "too many property writes from this player; slow down");
  }
  if (Status st = ValidatePropertyKey(key); !st.ok()) {
    return refuse(RejectReason::InvalidMessage, st.reason());
  }
  const PropertyValue value = ReadPropertyValue(set.value());
  if (Status st = ValidatePropertyValue(value); !st.ok()) {
    return refuse(RejectReason::InvalidMessage, st.reason());
  }
  const uint8_t authority_number = static_cast<uint8_t>(set.authority());
  if (authority_number > static_cast<uint8_t>(PropertyAuthority::kAnyone)) {
    return refuse(RejectReason::InvalidMessage, "unknown property authority");
  }
  const auto authority = static_cast<PropertyAuthority>(authority_number);
  if (budgets.max_property_value_bytes != 0 &&
      (value.type == PropertyType::kString || value.type == PropertyType::kBytes) &&
      value.text.size() > budgets.max_property_value_bytes) {
    env_.counters->RefuseOverBudget(BudgetKind::kPropertyValueBytes);
    return refuse(RejectReason::OverBudget, "over budget: property_value_bytes");
  }
  const Entity* entity = nullptr;
  if (entity_id != 0) {
    entity = room_.FindEntity(entity_id);
    if (entity == nullptr) return refuse(RejectReason::UnknownEntity, "no such entity");
  }
  const StoredProperty* current = properties_.Find(entity_id, key);
  // Authority: who owns the property (the entity's owner; the room property's creator, or the
  // writer creating it).
  const bool is_owner = entity != nullptr ? OwnsEntity(*entity, player)
                                          : (current == nullptr || current->owner == player);
  if (current != nullptr && current->authority == PropertyAuthority::kOwner && !is_owner) {
    return refuse(RejectReason::NotOwner, "only the owner may write this property");
  }
  if (current == nullptr && authority == PropertyAuthority::kOwner && !is_owner) {
    return refuse(RejectReason::NotOwner, "only the entity's owner may create an owner-only property");
  }
  // Compare-and-set.
  const uint32_t version = current != nullptr ? current->version : 0;
  if (set.check_version() && set.expected_version() != version) {
    ++property_stats_.conflicts;
    RelayCounters::Inc(env_.counters->property_conflicts);
    flatbuffers::FlatBufferBuilder fbb(128 + (current ? current->value.text.size() : 0));
    const auto key_offset = fbb.CreateString(key.data(), key.size());
    flatbuffers::Offset<schema::PropertyValue> now_value;
    if (current != nullptr) now_value = WritePropertyValue(fbb, current->value);
    FinishControl(fbb, schema::CreatePropertyConflict(fbb, set.request_id(), entity_id, key_offset,
                                                      now_value, version,
                                                      current ? current->writer : 0));
    (void)link.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
    return;
  }
  // Budgets: the room's count and bytes.
  if (current == nullptr && budgets.max_properties != 0 &&
      properties_.count() >= budgets.max_properties) {
    env_.counters->RefuseOverBudget(BudgetKind::kRoomProperties);
    return refuse(RejectReason::OverBudget, "over budget: room_properties");
  }
  const size_t old_cost = current ? PropertyTable::CostOf(key, current->value) : 0;
  if (budgets.max_property_bytes != 0 &&
      properties_.bytes() - old_cost + PropertyTable::CostOf(key, value) >
          budgets.max_property_bytes) {
    env_.counters->RefuseOverBudget(BudgetKind::kRoomPropertyBytes);
    return refuse(RejectReason::OverBudget, "over budget: room_property_bytes");
  }
  PropertyRecord record;
  record.entity_id = entity_id;
  record.key.assign(key);
  record.value = value;
  record.version = version + 1;
  record.writer = player;
  record.owner = entity != nullptr ? 0 : (current != nullptr ? current->owner : player);
  record.authority = current != nullptr ? current->authority : authority;  // fixed at creation
  record.request_id = set.request_id();
  properties_.Put(entity_id, key,
                  StoredProperty{value, record.version, player, record.owner, record.authority,
                                 record.request_id});
  ++property_stats_.accepted;
  RelayCounters::Inc(env_.counters->property_writes);
  flatbuffers::FlatBufferBuilder fbb(128 + value.text.size());
  BuildPropertyChanged(fbb, record);
  BroadcastReliable({fbb.GetBufferPointer(), fbb.GetSize()}, 0);
}

void RoomHost::SendJoinProperties(uint32_t player_id) {
  auto member = room_.members().find(player_id);
  if (member == room_.members().end() || properties_.count() == 0) return;
  flatbuffers::FlatBufferBuilder fbb(256);
  for (const auto& [k, p] : properties_.all()) {
    PropertyRecord record{k.first, k.second, p.value, p.version, p.writer,
                          p.owner, p.authority, p.request_id};
    BuildPropertyChanged(fbb, record);
    SendToMember(player_id, member->second, {fbb.GetBufferPointer(), fbb.GetSize()});
  }
}

size_t RoomHost::RestoreProperties(
    std::vector<std::pair<PropertyTable::Key, StoredProperty>> properties) {
  size_t skipped = 0;
  for (auto& [k, p] : properties) {
    if ((k.first != 0 && room_.FindEntity(k.first) == nullptr) ||
        !ValidatePropertyKey(k.second).ok() || !ValidatePropertyValue(p.value).ok() ||
        p.version == 0 || properties_.Find(k.first, k.second) != nullptr) {
      ++skipped;
      continue;
    }
    properties_.Put(k.first, k.second, std::move(p));
  }
  return skipped;
}

}  // namespace edgephys
