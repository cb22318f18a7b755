// A ClientListener that records what a client learns about properties, and helpers shared by
// the property integration tests (JoinAll comes with it).
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "client/client.h"
#include "edgephys/schema/control_generated.h"
#include "tests/integration/join_all.h"

namespace edgephys::testing {

struct PropertyInbox : ClientListener {
  std::vector<PropertyRecord> changes;
  std::vector<PropertyRecord> conflicts;
  std::vector<uint16_t> errors;
  std::vector<std::string> error_details;
  std::vector<uint32_t> spawned;
  void OnPropertyChanged(const PropertyRecord& p) override { changes.push_back(p); }
  void OnPropertyConflict(const PropertyRecord& p) override { conflicts.push_back(p); }
  void OnError(uint16_t reason, uint32_t, std::string_view detail) override {
    errors.push_back(reason);
    error_details.emplace_back(detail);
  }
  void OnEntitySpawned(const RemoteEntity& e) override { spawned.push_back(e.id); }
  // The versions of (entity, key) this client was told of, in order.
  std::vector<uint32_t> Versions(uint32_t entity, const std::string& key) const {
    std::vector<uint32_t> v;
    for (const PropertyRecord& p : changes) {
      if (p.entity_id == entity && p.key == key) v.push_back(p.version);
    }
    return v;
  }
  size_t Count(schema::RejectReason reason) const {
    return std::count(errors.begin(), errors.end(), static_cast<uint16_t>(reason));
  }
};

inline std::vector<uint32_t> OneTo(uint32_t n) {
  std::vector<uint32_t> v(n);
  for (uint32_t i = 0; i < n; ++i) v[i] = i + 1;
  return v;
}

}  // namespace edgephys::testing
