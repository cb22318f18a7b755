#include "relay/admin/admin_routes.h"

#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <set>

#include "protocol/join_token.h"
#include "relay/admin/monitor_page.h"
#include "relay/admin/room_map.h"

namespace edgephys::admin {
namespace {

using nlohmann::json;
using Method = AdminRoute::Method;

// Refuses fields outside `allowed`; empty string when fine, else the message.
std::string UnknownField(const json& body, const std::set<std::string>& allowed) {
  for (const auto& [key, value] : body.items()) {
    if (allowed.count(key) == 0) return "unknown field '" + key + "'";
  }
  return {};
}

// The optional "reason" of a kick or close: a string of at most kMaxReasonBytes.
bool ReadReason(const json& body, const std::string& fallback, std::string* reason,
                AdminReply* error) {
  if (std::string bad = UnknownField(body, {"reason"}); !bad.empty()) {
    *error = AdminError(400, "invalid_request", bad + " (allowed: reason)");
    return false;
  }
  auto it = body.find("reason");
  if (it == body.end()) {
    *reason = fallback;
    return true;
  }
  if (!it->is_string() || it->get<std::string>().size() > kMaxReasonBytes) {
    *error = AdminError(400, "invalid_request", "'reason' must be a string of at most 256 bytes");
    return false;
  }
  *reason = it->get<std::string>();
  return true;
}

bool ParsePlayerId(const std::string& text, uint32_t* out) {
  if (text.empty() || text.size() > 10) return false;
  for (char c : text) {
    if (c < '0' || c > '9') return false;
  }
  unsigned long long v = std::strtoull(text.c_str(), nullptr, 10);
  if (v == 0 || v > UINT32_MAX) return false;
  *out = static_cast<uint32_t>(v);
  return true;
}

// A room id from the path (admin_routes.h): 1..kMaxRoomNameSize bytes.
bool CheckRoomId(const std::string& id, AdminReply* error) {
  if (!id.empty() && id.size() <= kMaxRoomNameSize) return true;
  *error = AdminError(400, "invalid_request",
                      "the room id must be 1.." + std::to_string(kMaxRoomNameSize) +
                          " bytes (it has " + std::to_string(id.size()) + ")");
  return false;
}

// GET /v1/rooms/{id}/map?limit=N: N an integer in 1..kMaxMapEntities; no other parameter.
bool ReadMapLimit(const std::multimap<std::string, std::string>& query, size_t* limit,
                  AdminReply* error) {
  const std::string range = "1.." + std::to_string(kMaxMapEntities);
  *limit = kMaxMapEntities;
  for (const auto& [name, value] : query) {
    if (name != "limit") {
      *error = AdminError(400, "invalid_request",
                          "unknown query parameter '" + name + "' (allowed: limit)");
      return false;
    }
    if (query.count("limit") > 1) {
      *error = AdminError(400, "invalid_request", "'limit' given more than once");
      return false;
    }
    bool digits = !value.empty() && value.size() <= 6;
    for (char c : value) digits = digits && c >= '0' && c <= '9';
    const unsigned long v = digits ? std::strtoul(value.c_str(), nullptr, 10) : 0;
    if (v < 1 || v > kMaxMapEntities) {
      *error = AdminError(400, "invalid_request", "'limit' must be an integer in " + range);
      return false;
    }
    *limit = v;
  }
  return true;
}

}  // namespace

std::vector<AdminRoute> AdminRoutes(AdminBackend& b) {
  std::vector<AdminRoute> routes;
  auto add = [&](Method m, std::string pattern, bool needs_key,
                 std::function<AdminReply(const AdminRequest&)> handler) {
    routes.push_back({m, std::move(pattern), needs_key, std::move(handler), nullptr, nullptr});
  };

  // Probes: no key (Kubernetes and load balancers call them).
  add(Method::kGet, "/healthz", false, [&b](const AdminRequest&) { return b.Health(); });
  add(Method::kGet, "/readyz", false, [&b](const AdminRequest&) { return b.Ready(); });

  add(Method::kGet, "/v1/rooms", true, [&b](const AdminRequest&) { return b.ListRooms(); });
  add(Method::kPost, "/v1/rooms", true, [&b](const AdminRequest& r) { return b.CreateRoom(r.body); });
  add(Method::kGet, "/v1/rooms/([^/]+)", true, [&b](const AdminRequest& r) {
    AdminReply error;
    if (!CheckRoomId(r.params[0], &error)) return error;
    return b.GetRoom(r.params[0]);
  });
  add(Method::kGet, "/v1/rooms/([^/]+)/map", true, [&b](const AdminRequest& r) {
    AdminReply error;
    size_t limit = 0;
    if (!CheckRoomId(r.params[0], &error) || !ReadMapLimit(r.query, &limit, &error)) return error;
    return b.GetRoomMap(r.params[0], limit);
  });
  add(Method::kDelete, "/v1/rooms/([^/]+)", true, [&b](const AdminRequest& r) {
    std::string reason;
    AdminReply error;
    if (!CheckRoomId(r.params[0], &error)) return error;
    if (!ReadReason(r.body, "the room was closed by the operator", &reason, &error)) return error;
    return b.CloseRoom(r.params[0], reason);
  });
  add(Method::kPost, "/v1/rooms/([^/]+)/members/([^/]+)/kick", true, [&b](const AdminRequest& r) {
    AdminReply error;
    if (!CheckRoomId(r.params[0], &error)) return error;
    uint32_t player = 0;
    if (!ParsePlayerId(r.params[1], &player)) {
      return AdminError(400, "invalid_request", "the player id must be an integer in 1..4294967295");
    }
    std::string reason;
    if (!ReadReason(r.body, "kicked by the operator", &reason, &error)) return error;
    return b.Kick(r.params[0], player, reason);
  });
  add(Method::kPost, "/v1/drain", true, [&b](const AdminRequest& r) {
    if (std::string bad = UnknownField(r.body, {"deadline_s"}); !bad.empty()) {
      return AdminError(400, "invalid_request", bad + " (allowed: deadline_s)");
    }
    double deadline = 300;
    if (auto it = r.body.find("deadline_s"); it != r.body.end()) {
      deadline = it->is_number() ? it->get<double>() : -1;
      if (!std::isfinite(deadline) || deadline < 0 || deadline > 86400) {
        return AdminError(400, "invalid_request", "'deadline_s' must be a number in [0, 86400]");
      }
    }
    return b.Drain(deadline);
  });

  // The monitor page holds no data; its script asks the key of the operator (docs/operations.md).
  routes.push_back({Method::kGet, "/monitor", false, nullptr, kMonitorPage, "text/html; charset=utf-8"});
  return routes;
}

}  // namespace edgephys::admin
