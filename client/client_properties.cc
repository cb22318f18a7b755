// Client properties (client/client.h "Properties", docs/protocol.md "Properties"): writes and
// compare-and-set writes, the room's properties as the relay announced them, conflicts.
#include <flatbuffers/flatbuffers.h>

#include "client/client_impl.h"
#include "protocol/handshake.h"
#include "protocol/property_codec.h"

namespace edgephys {
namespace {

// The fields a PropertyChanged and a PropertyConflict both carry; `value` is the message's value
// (PropertyChanged::value, PropertyConflict::current).
template <typename Message>
PropertyRecord ReadRecord(const Message& m, const schema::PropertyValue* value) {
  PropertyRecord r;
  r.entity_id = m.entity_id();
  if (m.key() != nullptr) r.key = m.key()->str();
  r.value = ReadPropertyValue(value);
  r.version = m.version();
  r.writer = m.writer();
  r.request_id = m.request_id();
  return r;
}

}  // namespace

Result<uint32_t> Client::Impl::WriteProperty(uint32_t entity_id, std::string_view key,
                                             const PropertyValue& value,
                                             PropertyAuthority authority, bool check_version,
                                             uint32_t expected_version) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (Status st = ValidatePropertyKey(key); !st.ok()) return st;
  if (Status st = ValidatePropertyValue(value); !st.ok()) return st;
  if (authority != PropertyAuthority::kOwner && authority != PropertyAuthority::kAnyone) {
    return Status::InvalidArgument("unknown property authority");
  }
  if (entity_id != 0 && owned_.count(entity_id) == 0 && entities_.count(entity_id) == 0) {
    return Status::NotFound("no such entity in the room");
  }
  const uint32_t request_id = ++last_property_request_ == 0 ? ++last_property_request_
                                                            : last_property_request_;
  flatbuffers::FlatBufferBuilder fbb(96 + value.text.size());
  const auto key_offset = fbb.CreateString(key.data(), key.size());
  const auto value_offset = WritePropertyValue(fbb, value);
  FinishControl(fbb, schema::CreatePropertySet(fbb, entity_id, key_offset, value_offset,
                                               check_version, expected_version,
                                               static_cast<schema::PropertyAuthority>(authority),
                                               request_id));
  if (Status st = connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()}); !st.ok()) {
    return st;
  }
  return request_id;
}

void Client::Impl::OnPropertyMessage(const schema::ControlMessage& msg) {
  if (const auto* c = msg.body_as_PropertyChanged()) {
    PropertyRecord r = ReadRecord(*c, c->value());
    r.owner = c->owner();
    r.authority = static_cast<PropertyAuthority>(c->authority());
    // What a relay sends is checked like what it receives: a bad record is ignored.
    if (!ValidatePropertyKey(r.key).ok() || !ValidatePropertyValue(r.value).ok()) return;
    // An entity's properties follow its Spawn; one for an entity not (or no longer) known is
    // late news of a despawned entity.
    if (r.entity_id != 0 && owned_.count(r.entity_id) == 0 && entities_.count(r.entity_id) == 0) {
      return;
    }
    PropertyRecord& stored = properties_[PropertyKey(r.entity_id, r.key)];
    stored = std::move(r);
    listener_->OnPropertyChanged(stored);
    return;
  }
  if (const auto* c = msg.body_as_PropertyConflict()) {
    PropertyRecord r = ReadRecord(*c, c->current());
    if (r.version != 0 && !ValidatePropertyValue(r.value).ok()) return;
    if (r.version == 0) r.value = PropertyValue{};
    if (const auto it = properties_.find(PropertyKey(r.entity_id, r.key)); it != properties_.end()) {
      r.owner = it->second.owner;
      r.authority = it->second.authority;
    }
    listener_->OnPropertyConflict(r);
  }
}

void Client::Impl::ForgetEntityProperties(uint32_t entity_id) {
  if (entity_id == 0) return;
  auto it = properties_.lower_bound(PropertyKey(entity_id, std::string()));
  while (it != properties_.end() && it->first.first == entity_id) it = properties_.erase(it);
}

Result<uint32_t> Client::SetProperty(uint32_t entity_id, std::string_view key,
                                     const PropertyValue& value, PropertyAuthority authority) {
  return impl_->WriteProperty(entity_id, key, value, authority, false, 0);
}

Result<uint32_t> Client::CompareAndSetProperty(uint32_t entity_id, std::string_view key,
                                               const PropertyValue& value,
                                               uint32_t expected_version,
                                               PropertyAuthority authority) {
  return impl_->WriteProperty(entity_id, key, value, authority, true, expected_version);
}

const PropertyRecord* Client::FindProperty(uint32_t entity_id, std::string_view key) const {
  const auto it = impl_->properties_.find(PropertyKey(entity_id, std::string(key)));
  return it == impl_->properties_.end() ? nullptr : &it->second;
}

const std::map<PropertyKey, PropertyRecord>& Client::properties() const {
  return impl_->properties_;
}

}  // namespace edgephys
