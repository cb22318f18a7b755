// CommandQueue: runs functions on the relay's thread on behalf of other threads (the admin
// HTTP server's), and hands their results back. The relay is single-threaded: nothing outside
// its thread may touch its state, so every admin operation is a command queued here and run
// by the relay loop (RunPending, once per Relay::Update).
//
// Thread-safety: Call() from any thread, RunPending() and Close() from the relay's thread.
// Failure modes: Call() returns nullopt if the relay does not run the command within the
// timeout (a stalled or busy loop; the caller answers 503) or the queue is closed. A command
// that timed out may still run later; it owns copies of everything it uses, and its result is
// then dropped. The queue holds at most kMaxPending commands; beyond that Call() fails at once.
#pragma once

#include <chrono>
#include <condition_variable>
#include <cstddef>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>

#include "relay/admin/admin_api.h"

namespace edgephys::admin {

class CommandQueue {
 public:
  // A command gets the relay's clock (seconds, monotonic) and answers with a reply.
  using Command = std::function<AdminReply(double now)>;
  static constexpr size_t kMaxPending = 256;

  // Queues `command` and waits up to `timeout` for the relay thread to run it.
  std::optional<AdminReply> Call(Command command, std::chrono::milliseconds timeout);
  // Relay thread: runs every command queued so far. O(commands).
  void RunPending(double now);
  // Relay thread, on exit: later and waiting Calls fail.
  void Close();

 private:
  struct Slot {
    Command command;
    std::optional<AdminReply> reply;
    bool done = false;
  };
  std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::shared_ptr<Slot>> queue_;
  bool closed_ = false;
};

}  // namespace edgephys::admin
