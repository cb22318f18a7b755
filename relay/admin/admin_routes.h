// The admin API's route table: every endpoint of docs/admin-api.md, in one place
// (admin_routes.cc). AdminHttpServer registers each route with cpp-httplib and does what all
// routes share (the bearer key, the body limit, JSON parsing, error shapes); a handler only
// validates its own parameters and calls the AdminBackend.
//
// To add an endpoint: append an AdminRoute to the table in admin_routes.cc (and a method to
// AdminBackend if it needs the relay), document it in docs/admin-api.md, and test it in
// tests/admin/admin_api_test.sh.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "relay/admin/admin_api.h"

namespace edgephys::admin {

struct AdminRequest {
  std::vector<std::string> params;  // the pattern's capture groups, URL-decoded
  nlohmann::json body;              // the parsed body (an object; {} when the body is empty)
  std::multimap<std::string, std::string> query;  // the URL's query parameters, decoded
};

struct AdminRoute {
  enum class Method { kGet, kPost, kDelete };
  Method method;
  std::string pattern;   // an ECMAScript regex over the whole path
  bool needs_key = true;
  // A JSON route's handler. Unset for a static page.
  std::function<AdminReply(const AdminRequest&)> handler;
  // A static page (the monitor): served as is with this content type.
  const char* page = nullptr;
  const char* content_type = nullptr;
};

// The table; the handlers call `backend`, which must outlive them.
std::vector<AdminRoute> AdminRoutes(AdminBackend& backend);

// A room id in a path is checked before the relay is asked: 1..kMaxRoomNameSize (64) bytes
// once URL-decoded, else 400 invalid_request. Any byte is allowed otherwise (join tokens may
// name rooms with any bytes); an id no room has gets 404 room_not_found.

// Largest operator text (kick and close reasons), bytes; the relay sends it to clients.
inline constexpr size_t kMaxReasonBytes = 256;

}  // namespace edgephys::admin
