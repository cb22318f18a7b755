// PropertyTable: the properties one room holds (docs/protocol.md, "Properties"): room
// properties (entity 0) and entity properties, each under (entity id, key), with its value,
// version, last writer, owner and authority, and what they cost against the room's property
// budgets (RoomBudgets::max_properties, max_property_bytes). The rules that change it (who may
// write, compare-and-set, budgets) live in RoomHost::SetProperty (relay/room_properties.cc).
//
// Thread-safety: none (the room's thread). Memory: O(properties + their bytes).
// Cost: O(log n) per lookup or write; EraseEntity O(log n + that entity's properties).
#pragma once

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>

#include "protocol/property_value.h"

namespace edgephys {

struct StoredProperty {
  PropertyValue value;
  uint32_t version = 0;     // 1 on creation, +1 per accepted write
  uint32_t writer = 0;      // player id of the last accepted write
  uint32_t owner = 0;       // room properties: the creator; entity properties: 0 (the entity's
                            // owner decides)
  PropertyAuthority authority = PropertyAuthority::kOwner;
  uint32_t request_id = 0;  // the last writer's request id
};

class PropertyTable {
 public:
  using Key = std::pair<uint32_t, std::string>;  // (entity id, 0 for the room; key)
  // What a property costs in max_property_bytes: its key and value bytes.
  static size_t CostOf(std::string_view key, const PropertyValue& value) {
    return key.size() + value.size();
  }

  const StoredProperty* Find(uint32_t entity_id, std::string_view key) const {
    auto it = properties_.find(Key(entity_id, std::string(key)));
    return it == properties_.end() ? nullptr : &it->second;
  }
  // Inserts or replaces; keeps bytes() and bumps changes().
  const StoredProperty& Put(uint32_t entity_id, std::string_view key, StoredProperty property) {
    auto [it, fresh] = properties_.try_emplace(Key(entity_id, std::string(key)));
    if (!fresh) bytes_ -= CostOf(key, it->second.value);
    bytes_ += CostOf(key, property.value);
    it->second = std::move(property);
    ++changes_;
    return it->second;
  }
  // Removes every property of `entity_id` (not 0); returns how many.
  size_t EraseEntity(uint32_t entity_id) {
    auto it = properties_.lower_bound(Key(entity_id, std::string()));
    size_t n = 0;
    while (it != properties_.end() && it->first.first == entity_id) {
      bytes_ -= CostOf(it->first.second, it->second.value);
      it = properties_.erase(it);
      ++n;
    }
    if (n > 0) ++changes_;
    return n;
  }
  // Every property, room properties first, then by entity id and key.
  const std::map<Key, StoredProperty>& all() const { return properties_; }
  size_t count() const { return properties_.size(); }
  size_t bytes() const { return bytes_; }
  // Bumped on every change (cluster snapshots are written when it moved).
  uint64_t changes() const { return changes_; }

 private:
  std::map<Key, StoredProperty> properties_;
  size_t bytes_ = 0;
  uint64_t changes_ = 0;
};

}  // namespace edgephys
