#include "relay/admin/relay_admin.h"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <memory>

#include "relay/admin/room_map.h"
#include "relay/admin/room_request.h"

namespace edgephys::admin {
namespace {

using nlohmann::json;

int64_t SteadyNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

}  // namespace

RelayAdmin::RelayAdmin(Relay* relay, const RoomConfig& defaults, std::chrono::milliseconds timeout)
    : relay_(relay), defaults_(defaults), timeout_(timeout), last_tick_ns_(SteadyNs()) {}

void RelayAdmin::Tick(double now) {
  last_tick_ns_.store(SteadyNs(), std::memory_order_relaxed);
  if (now - last_sample_ >= 1.0) {
    inspector_.Sample(*relay_, now);
    last_sample_ = now;
  }
  queue_.RunPending(now);
  if (draining_.load(std::memory_order_relaxed)) DriveDrain(now);
}

void RelayAdmin::DriveDrain(double now) {
  if (exit_) return;
  if (relay_->client_count() == 0) {
    spdlog::info("drain: no client left; exiting");
    exit_ = true;
    return;
  }
  if (!closing_all_ && now >= drain_deadline_) {
    spdlog::info("drain: deadline reached; disconnecting {} clients", relay_->client_count());
    relay_->CloseAllSessions("the relay is shutting down (drain deadline)", now);
    closing_all_ = true;
    closing_since_ = now;
  }
  if (closing_all_ && now - closing_since_ > Session::kCloseGraceS + 0.5) exit_ = true;
}

AdminReply RelayAdmin::OnRelay(CommandQueue::Command command) {
  auto reply = queue_.Call(std::move(command), timeout_);
  if (!reply) return AdminError(503, "relay_busy", "the relay did not answer in time");
  return std::move(*reply);
}

AdminReply RelayAdmin::ListRooms() {
  return OnRelay([this](double) {
    AdminReply r;
    r.body = inspector_.ListRooms(*relay_);
    r.body["draining"] = !relay_->admitting();
    r.body["clients"] = relay_->client_count();
    return r;
  });
}

AdminReply RelayAdmin::GetRoom(const std::string& id) {
  return OnRelay([this, id](double now) {
    auto view = inspector_.DescribeRoom(*relay_, id, now);
    if (!view) return AdminError(404, "room_not_found", "no room '" + id + "' on this relay");
    AdminReply r;
    r.body = std::move(*view);
    return r;
  });
}

AdminReply RelayAdmin::GetRoomMap(const std::string& id, size_t limit) {
  // The relay's thread copies the entities; the JSON is built here, on the HTTP thread.
  auto snapshot = std::make_shared<RoomMapSnapshot>();
  AdminReply reply = OnRelay([this, id, limit, snapshot](double) {
    auto it = relay_->rooms().find(id);
    if (it == relay_->rooms().end()) {
      return AdminError(404, "room_not_found", "no room '" + id + "' on this relay");
    }
    *snapshot = TakeRoomMap(it->second->room(), limit);
    return AdminReply{};
  });
  if (reply.status == 200) reply.body = RoomMapJson(*snapshot);
  return reply;
}

AdminReply RelayAdmin::CreateRoom(const json& request) {
  Result<RoomRequest> parsed = ParseRoomRequest(request, defaults_);
  if (!parsed.ok()) {
    return AdminError(400, "invalid_request", std::string(parsed.status().reason()));
  }
  return OnRelay([this, req = std::move(*parsed)](double now) {
    if (!relay_->admitting()) return AdminError(503, "draining", "the relay is draining");
    if (relay_->rooms().count(req.id) != 0) {
      return AdminError(409, "room_exists", "room '" + req.id + "' already exists");
    }
    Status st = relay_->CreateRoom(req.id, req.config, now);
    if (!st.ok()) return AdminError(400, "invalid_request", std::string(st.reason()));
    spdlog::info("room '{}' created by the operator", req.id);
    AdminReply r;
    r.status = 201;
    r.body = *inspector_.DescribeRoom(*relay_, req.id, now);
    return r;
  });
}

AdminReply RelayAdmin::CloseRoom(const std::string& id, const std::string& reason) {
  return OnRelay([this, id, reason](double now) {
    auto it = relay_->rooms().find(id);
    if (it == relay_->rooms().end()) {
      return AdminError(404, "room_not_found", "no room '" + id + "' on this relay");
    }
    size_t members = it->second->room().size();
    (void)relay_->CloseRoom(id, reason, now);
    AdminReply r;
    r.body = {{"closed", id}, {"disconnected", members}};
    return r;
  });
}

AdminReply RelayAdmin::Kick(const std::string& room, uint32_t player_id, const std::string& reason) {
  return OnRelay([this, room, player_id, reason](double now) {
    if (relay_->rooms().count(room) == 0) {
      return AdminError(404, "room_not_found", "no room '" + room + "' on this relay");
    }
    if (!relay_->Kick(room, player_id, reason, now).ok()) {
      return AdminError(404, "member_not_found",
                        "player " + std::to_string(player_id) + " is not in room '" + room + "'");
    }
    AdminReply r;
    r.body = {{"kicked", player_id}, {"room", room}, {"reason", reason}};
    return r;
  });
}

AdminReply RelayAdmin::Drain(double deadline_s) {
  return OnRelay([this, deadline_s](double now) {
    relay_->set_admitting(false);
    drain_deadline_ = std::min(drain_deadline_, now + deadline_s);
    if (!draining_.exchange(true)) {
      spdlog::info("drain: admission stopped; exiting when empty or in {:.0f} s", deadline_s);
    }
    AdminReply r;
    r.status = 202;
    r.body = {{"draining", true},
              {"deadline_in_s", drain_deadline_ - now},
              {"clients", relay_->client_count()}};
    return r;
  });
}

AdminReply RelayAdmin::Health() {
  double idle_s = static_cast<double>(SteadyNs() - last_tick_ns_.load(std::memory_order_relaxed)) / 1e9;
  if (idle_s > kStallS) {
    return AdminError(503, "relay_stalled",
                      "the relay loop has not run for " + std::to_string(static_cast<int>(idle_s)) + " s");
  }
  AdminReply r;
  r.body = {{"status", "ok"}};
  return r;
}

AdminReply RelayAdmin::Ready() {
  if (draining_.load(std::memory_order_relaxed)) {
    return AdminError(503, "draining", "the relay is draining");
  }
  AdminReply r = Health();
  if (r.status == 200) r.body = {{"ready", true}};
  return r;
}

}  // namespace edgephys::admin
