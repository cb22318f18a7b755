#include "relay/admin/room_request.h"

#include <cmath>
#include <cstdio>
#include <set>

#include "protocol/join_token.h"
#include "protocol/quantize.h"
#include "protocol/types.h"

namespace edgephys::admin {
namespace {

using nlohmann::json;

Status Invalid(const std::string& detail) {
  return Status::InvalidArgument("invalid room request", detail);
}

Status CheckKnown(const json& object, std::string_view where, const std::set<std::string>& known) {
  if (!object.is_object()) return Invalid(std::string(where) + " must be a JSON object");
  for (const auto& [key, value] : object.items()) {
    if (known.count(key) == 0) {
      std::string allowed;
      for (const auto& k : known) allowed += (allowed.empty() ? "" : ", ") + k;
      return Invalid("unknown field '" + std::string(where) + key + "' (allowed: " + allowed + ")");
    }
  }
  return Status::Ok();
}

// A number in [lo, hi]; `integer` also refuses fractions.
Status ReadNumber(const json& object, const std::string& key, std::string_view where, double lo,
                  double hi, bool integer, double* out) {
  auto it = object.find(key);
  if (it == object.end()) return Status::Ok();
  const std::string name = std::string(where) + key;
  if (!it->is_number()) return Invalid("'" + name + "' must be a number");
  double v = it->get<double>();
  if (!std::isfinite(v) || v < lo || v > hi || (integer && v != std::floor(v))) {
    char range[96];
    std::snprintf(range, sizeof(range), "%s in [%g, %g]", integer ? "an integer" : "a number", lo,
                  hi);
    return Invalid("'" + name + "' must be " + range);
  }
  *out = v;
  return Status::Ok();
}

}  // namespace

bool IsValidRoomId(std::string_view id) {
  if (id.empty() || id.size() > kMaxRoomNameSize) return false;
  for (unsigned char c : id) {
    if (c < 0x20 || c == 0x7f || c == '/') return false;
  }
  return true;
}

Result<RoomRequest> ParseRoomRequest(const json& body, const RoomConfig& defaults) {
  Status st = CheckKnown(body, "", {"id", "capacity", "ttl_s", "tick_rate_hz", "send_rates_hz",
                                    "physics", "bounds", "max_entities_per_player"});
  if (!st.ok()) return st;
  RoomRequest r;
  r.config = defaults;
  auto id = body.find("id");
  if (id == body.end() || !id->is_string()) return Invalid("'id' (a string) is required");
  r.id = id->get<std::string>();
  if (!IsValidRoomId(r.id)) {
    return Invalid("'id' must be 1..64 bytes without '/' or control characters");
  }
  RoomConfig& c = r.config;
  double v = c.capacity;
  if (st = ReadNumber(body, "capacity", "", 1, kEntityIdBlock - 1, true, &v); !st.ok()) return st;
  c.capacity = static_cast<uint32_t>(v);
  if (st = ReadNumber(body, "ttl_s", "", 0, 7 * 86400, false, &c.idle_ttl_s); !st.ok()) return st;
  if (st = ReadNumber(body, "tick_rate_hz", "", 1, 1000, false, &c.tick_rate_hz); !st.ok()) {
    return st;
  }
  v = c.max_entities_per_player;
  if (st = ReadNumber(body, "max_entities_per_player", "", 1, kEntityIdBlock - 1, true, &v);
      !st.ok()) {
    return st;
  }
  c.max_entities_per_player = static_cast<uint32_t>(v);
  if (auto p = body.find("physics"); p != body.end()) {
    if (!p->is_boolean()) return Invalid("'physics' must be true or false");
    c.physics = p->get<bool>();
  }
  if (auto rates = body.find("send_rates_hz"); rates != body.end()) {
    if (st = CheckKnown(*rates, "send_rates_hz.",
                             {"critical", "normal", "ambient", "soft_touched"}); !st.ok()) {
      return st;
    }
    ReplicationConfig& rep = c.replication;
    for (auto [key, field] : {std::pair{"critical", &rep.critical_hz},
                              std::pair{"normal", &rep.normal_hz},
                              std::pair{"ambient", &rep.ambient_hz},
                              std::pair{"soft_touched", &rep.soft_touched_hz}}) {
      if (st = ReadNumber(*rates, key, "send_rates_hz.", 1, 240, false, field); !st.ok()) return st;
    }
  }
  if (auto bounds = body.find("bounds"); bounds != body.end()) {
    if (st = CheckKnown(*bounds, "bounds.", {"half_extent_m"}); !st.ok()) return st;
    double h = c.replication.bounds_half_extent_m;
    if (st = ReadNumber(*bounds, "half_extent_m", "bounds.", 1, 100000, false, &h); !st.ok()) {
      return st;
    }
    c.replication.bounds_half_extent_m = static_cast<float>(h);
    if (!MakeQuantizationParams(QuantizationOf(c.replication)).ok()) {
      return Invalid("'bounds.half_extent_m' is too large for the relay's position step (at most "
                     "2^30 steps per axis)");
    }
  }
  return r;
}

json RoomConfigJson(const RoomConfig& c) {
  return {{"capacity", c.capacity},
          {"ttl_s", c.idle_ttl_s},
          {"tick_rate_hz", c.tick_rate_hz},
          {"send_rates_hz",
           {{"critical", c.replication.critical_hz},
            {"normal", c.replication.normal_hz},
            {"ambient", c.replication.ambient_hz},
            {"soft_touched", c.replication.soft_touched_hz}}},
          {"physics", c.physics},
          {"bounds", {{"half_extent_m", c.replication.bounds_half_extent_m}}},
          {"max_entities_per_player", c.max_entities_per_player}};
}

}  // namespace edgephys::admin
