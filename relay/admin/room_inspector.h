// RoomInspector: the admin API's views of a relay's rooms and members as JSON
// (docs/admin-api.md: GET /v1/rooms and GET /v1/rooms/{id}), and the byte rates they show.
//
// Rates are measured, not guessed: Sample() records every member connection's byte counters
// (ConnectionStats) about once a second, and a member's bytes/s is the change between its two
// latest samples (0 until it has two). A room's rates are its members' sums.
//
// Thread-safety: the relay's thread only (it reads the Relay). Cost: Sample() and the views
// are O(members) (DescribeRoom also O(entities)); nothing runs per packet.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <unordered_map>

#include <nlohmann/json.hpp>

#include "relay/relay.h"

namespace edgephys::admin {

class RoomInspector {
 public:
  void Sample(const Relay& relay, double now);

  // {"rooms": [summary...]}; a summary is id, players, capacity, entities, physics
  // {enabled, active, realtime_factor, worker}, tick_rate_hz, state_format (the
  // number its Joined announces, RoomHost::state_format), bytes_in_per_s, bytes_out_per_s.
  nlohmann::json ListRooms(const Relay& relay) const;
  // The summary plus config, members (player_id, connection_id, address, rtt_ms, rtt_var_ms,
  // loss, bytes_in_per_s, bytes_out_per_s, pending_reliable_bytes, connected_for_s, entities)
  // and entity counts by owner. nullopt if there is no such room.
  std::optional<nlohmann::json> DescribeRoom(const Relay& relay, const std::string& id,
                                             double now) const;

 private:
  struct Rate {
    uint64_t bytes_in = 0, bytes_out = 0;
    double at = 0;
    double in_per_s = 0, out_per_s = 0;
  };
  nlohmann::json Summary(const Relay& relay, const RoomHost& room) const;
  const Rate* RateOf(uint32_t connection_id) const;

  std::unordered_map<uint32_t, Rate> rates_;  // by connection id
};

}  // namespace edgephys::admin
