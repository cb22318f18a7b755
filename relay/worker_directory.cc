#include "relay/worker_directory.h"

#include <spdlog/spdlog.h>

#include "protocol/byte_io.h"

namespace edgephys {

WorkerDirectory::~WorkerDirectory() {
  // Links outliving the directory would call Unregister on a dead object: make them forget us.
  for (auto& [key, link] : links_) link->set_registry(nullptr);
}

void WorkerDirectory::Attach(uint32_t worker_id, WorkerChannel* channel) {
  workers_[worker_id] = channel;
}

void WorkerDirectory::Detach(uint32_t worker_id) {
  if (workers_.erase(worker_id) == 0) return;
  for (auto& [key, link] : links_) {
    if (link->worker() == worker_id) link->Detach();
  }
}

std::unique_ptr<PhysicsLink> WorkerDirectory::Place(uint32_t exclude_worker, double now) {
  uint32_t best = 0;
  size_t best_rooms = 0;
  for (const auto& [id, channel] : workers_) {
    if (id == exclude_worker || !channel->WorkerConnected()) continue;
    size_t rooms = 0;
    for (const auto& [key, link] : links_) rooms += link->worker() == id;
    if (best == 0 || rooms < best_rooms) {
      best = id;
      best_rooms = rooms;
    }
  }
  if (best == 0) return std::make_unique<EmbeddedPhysicsLink>(config_, now);
  uint32_t handle = ++next_handle_;
  spdlog::info("PhyS: room handle {} on worker {:08x}", handle, best);
  auto link = std::make_unique<RemotePhysicsLink>(workers_.at(best), best, handle, config_, now);
  link->set_registry(this);
  links_[Key(best, handle)] = link.get();
  return link;
}

bool WorkerDirectory::RouteResult(uint32_t worker_id, const schema::WorkerResult& result,
                                  double now) {
  auto it = links_.find(Key(worker_id, result.room()));
  if (it == links_.end()) return false;
  it->second->ReceiveResult(result, now);
  return true;
}

bool WorkerDirectory::RouteStates(uint32_t worker_id, std::span<const uint8_t> payload,
                                  double now) {
  if (payload.size() < 5) return false;
  auto it = links_.find(Key(worker_id, LoadU32LE(payload.data() + 1)));
  if (it == links_.end()) return false;
  it->second->ReceiveStates(payload, now);
  return true;
}

void WorkerDirectory::Unregister(uint32_t worker_id, uint32_t handle) {
  links_.erase(Key(worker_id, handle));
}

}  // namespace edgephys
