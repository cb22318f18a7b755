// RelayAdmin: the admin API's operations on one Relay (docs/admin-api.md). The HTTP threads
// call its AdminBackend methods; each one validates its input where it is, then runs the
// operation as a command on the relay's thread (CommandQueue) and waits for the reply, at most
// `timeout` (then 503 relay_busy). Nothing here touches the Relay outside its thread.
//
// The relay's loop (relay/main.cc) calls Tick() after every Relay::Update: it runs the queued
// commands, samples byte rates once a second (RoomInspector) and drives a drain. A drain stops
// admission (Relay::set_admitting(false), /readyz 503) and ends when no client is left, or at
// its deadline, when the remaining clients are sent Disconnecting{ServerShutdown} and given
// Session::kCloseGraceS to acknowledge it; ShouldExit() then turns true.
//
// Thread-safety: AdminBackend methods from any thread; the constructor, Tick(), ShouldExit()
// and Close() from the relay's thread. The Relay must outlive this object.
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <limits>
#include <string>

#include "relay/admin/admin_api.h"
#include "relay/admin/command_queue.h"
#include "relay/admin/room_inspector.h"
#include "relay/relay.h"

namespace edgephys::admin {

class RelayAdmin final : public AdminBackend {
 public:
  // `defaults`: the relay's RoomConfig for fields a create request leaves out.
  RelayAdmin(Relay* relay, const RoomConfig& defaults,
             std::chrono::milliseconds timeout = std::chrono::milliseconds(2000));

  // --- Relay thread ---
  void Tick(double now);
  // A drain has finished: the process should shut the relay down and exit.
  bool ShouldExit() const { return exit_; }
  // Fails every waiting and later request (503); call before destroying the Relay.
  void Close() { queue_.Close(); }

  // --- AdminBackend (any thread) ---
  AdminReply ListRooms() override;
  AdminReply GetRoom(const std::string& id) override;
  AdminReply GetRoomMap(const std::string& id, size_t limit) override;
  AdminReply CreateRoom(const nlohmann::json& request) override;
  AdminReply CloseRoom(const std::string& id, const std::string& reason) override;
  AdminReply Kick(const std::string& room, uint32_t player_id, const std::string& reason) override;
  AdminReply Drain(double deadline_s) override;
  AdminReply Health() override;
  AdminReply Ready() override;

  // A loop that has not called Tick() for this long is reported unhealthy.
  static constexpr double kStallS = 5.0;

 private:
  AdminReply OnRelay(CommandQueue::Command command);
  void DriveDrain(double now);

  Relay* relay_;
  RoomConfig defaults_;
  std::chrono::milliseconds timeout_;
  CommandQueue queue_;
  std::atomic<bool> draining_{false};
  std::atomic<int64_t> last_tick_ns_;  // steady clock
  // Relay thread only.
  RoomInspector inspector_;
  double last_sample_ = -1e9;
  double drain_deadline_ = std::numeric_limits<double>::infinity();
  bool closing_all_ = false;
  double closing_since_ = 0;
  bool exit_ = false;
};

}  // namespace edgephys::admin
