// The JSON body of POST /v1/rooms (docs/admin-api.md) turned into a room name and a
// RoomConfig, or a precise error. Pure functions, no relay state; any thread.
//
//   {"id": "arena", "capacity": 16, "ttl_s": 600, "tick_rate_hz": 30,
//    "send_rates_hz": {"critical": 48, "normal": 12, "ambient": 6, "soft_touched": 24},
//    "physics": true, "bounds": {"half_extent_m": 100}, "max_entities_per_player": 1024}
//
// Only "id" is required; every other field defaults to the relay's room defaults (its flags).
// Unknown fields, wrong JSON types, non-integers where integers are due and values out of
// range are refused (kInvalidArgument, the message names the field and the allowed range).
#pragma once

#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "protocol/status.h"
#include "relay/relay_config.h"

namespace edgephys::admin {

struct RoomRequest {
  std::string id;
  RoomConfig config;
};

// `defaults` is the relay's RelayConfig::room_defaults.
Result<RoomRequest> ParseRoomRequest(const nlohmann::json& body, const RoomConfig& defaults);

// A room id an operator may use in a URL path: 1..64 bytes, no '/', no control characters.
bool IsValidRoomId(std::string_view id);

// The room config as JSON, in the request's shape (what GET /v1/rooms/{id} shows).
nlohmann::json RoomConfigJson(const RoomConfig& config);

}  // namespace edgephys::admin
