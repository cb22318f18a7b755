// The admin API's contract between its HTTP front (relay/admin/admin_http.h, which parses
// requests, checks the key and writes JSON) and whatever serves the operations
// (relay/admin/relay_admin.h for one relay; a cluster front may implement it too).
//
// Every operation returns an AdminReply: an HTTP status and a JSON body. Errors use the shape
// of docs/admin-api.md: {"error": {"code": "<snake_case code>", "message": "<one line>"}}.
//
// Thread-safety: the HTTP server calls an AdminBackend from its worker threads, several at
// once; implementations must be safe for that (RelayAdmin marshals onto the relay's thread).
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

namespace edgephys::admin {

struct AdminReply {
  int status = 200;
  nlohmann::json body = nlohmann::json::object();
};

// {"error": {"code": code, "message": message}} with HTTP `status`.
inline AdminReply AdminError(int status, std::string_view code, std::string_view message) {
  AdminReply r;
  r.status = status;
  r.body = {{"error", {{"code", code}, {"message", message}}}};
  return r;
}

class AdminBackend {
 public:
  virtual ~AdminBackend() = default;

  // GET /v1/rooms: every room's summary.
  virtual AdminReply ListRooms() = 0;
  // GET /v1/rooms/{id}: one room with its members and entity counts (404 room_not_found).
  virtual AdminReply GetRoom(const std::string& id) = 0;
  // GET /v1/rooms/{id}/map: the room's entities with positions and kinds, at most `limit`
  // (relay/admin/room_map.h; 404 room_not_found).
  virtual AdminReply GetRoomMap(const std::string& id, size_t limit) = 0;
  // POST /v1/rooms: `request` is the parsed JSON body (validated here: 400 invalid_request).
  virtual AdminReply CreateRoom(const nlohmann::json& request) = 0;
  // DELETE /v1/rooms/{id}: members are disconnected with `reason`.
  virtual AdminReply CloseRoom(const std::string& id, const std::string& reason) = 0;
  // POST /v1/rooms/{id}/members/{player}/kick.
  virtual AdminReply Kick(const std::string& room, uint32_t player_id,
                          const std::string& reason) = 0;
  // POST /v1/drain: stop admitting; the process exits when empty or after `deadline_s`.
  virtual AdminReply Drain(double deadline_s) = 0;
  // GET /healthz: 200 while the relay's loop runs, 503 if it stalled.
  virtual AdminReply Health() = 0;
  // GET /readyz: 200 when admitting, 503 while draining.
  virtual AdminReply Ready() = 0;
};

}  // namespace edgephys::admin
