#include "relay/admin/command_queue.h"

#include <exception>
#include <utility>
#include <vector>

namespace edgephys::admin {

std::optional<AdminReply> CommandQueue::Call(Command command, std::chrono::milliseconds timeout) {
  auto slot = std::make_shared<Slot>();
  slot->command = std::move(command);
  std::unique_lock lock(mu_);
  if (closed_ || queue_.size() >= kMaxPending) return std::nullopt;
  queue_.push_back(slot);
  cv_.wait_for(lock, timeout, [&] { return slot->done || closed_; });
  if (!slot->done) return std::nullopt;
  return std::move(slot->reply);
}

void CommandQueue::RunPending(double now) {
  std::deque<std::shared_ptr<Slot>> batch;
  {
    std::lock_guard lock(mu_);
    if (queue_.empty()) return;
    batch.swap(queue_);
  }
  for (auto& slot : batch) {
    AdminReply reply;
    try {  // outside the lock: commands touch the relay. A bug answers 500, the loop goes on.
      reply = slot->command(now);
    } catch (const std::exception& e) {
      reply = AdminError(500, "internal", e.what());
    }
    std::lock_guard lock(mu_);
    slot->reply = std::move(reply);
    slot->done = true;
  }
  cv_.notify_all();
}

void CommandQueue::Close() {
  std::lock_guard lock(mu_);
  closed_ = true;
  queue_.clear();
  cv_.notify_all();
}

}  // namespace edgephys::admin
