// WorkerDirectory: where rooms' PhyS runs. It knows the edgephys-phys workers attached to this
// relay, places a room's physics on the least loaded one (or embedded when none is attached),
// and routes what a worker sends back to the room link it is for. The relay's only path to
// remote PhyS; nothing else needs to know which PhysicsLink is remote.
//
// Ownership: the directory owns no links; a RemotePhysicsLink it made registers itself and
// unregisters when destroyed, so the directory must outlive every link it placed. Channels
// (worker sessions) are not owned; Detach() a worker before its channel goes.
// Thread-safety: the relay's thread. Cost: Place() is O(workers); routing is O(1).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <unordered_map>

#include "relay/physics_link.h"

namespace edgephys {

// Makes a PhysicsLink for a room (the interface RoomHost sees).
class PhysicsPlacement {
 public:
  virtual ~PhysicsPlacement() = default;
  // A link on the least loaded attached worker other than `exclude_worker` (0: none
  // excluded), else an embedded one. Never null.
  virtual std::unique_ptr<PhysicsLink> Place(uint32_t exclude_worker, double now) = 0;
};

class WorkerDirectory final : public PhysicsPlacement, public PhysicsLinkRegistry {
 public:
  explicit WorkerDirectory(const physics::PhysicsConfig& config) : config_(config) {}
  ~WorkerDirectory() override;
  WorkerDirectory(const WorkerDirectory&) = delete;
  WorkerDirectory& operator=(const WorkerDirectory&) = delete;

  // A worker session completed WorkerHello. `channel` must stay valid until Detach(id).
  void Attach(uint32_t worker_id, WorkerChannel* channel);
  // The worker is gone: its links stop sending (they report unhealthy and their rooms fail
  // over on the next step). No-op for an unknown id.
  void Detach(uint32_t worker_id);
  size_t workers() const { return workers_.size(); }

  std::unique_ptr<PhysicsLink> Place(uint32_t exclude_worker, double now) override;

  // From worker `worker_id`: a result or a state payload for one of its room handles.
  // Returns false (the caller counts a drop) when no link of that worker has that handle.
  bool RouteResult(uint32_t worker_id, const schema::WorkerResult& result, double now);
  bool RouteStates(uint32_t worker_id, std::span<const uint8_t> payload, double now);

  // PhysicsLinkRegistry: called by a placed RemotePhysicsLink's destructor.
  void Unregister(uint32_t worker_id, uint32_t handle) override;

 private:
  static uint64_t Key(uint32_t worker, uint32_t handle) {
    return (uint64_t{worker} << 32) | handle;
  }
  physics::PhysicsConfig config_;
  std::map<uint32_t, WorkerChannel*> workers_;            // by worker connection id
  std::unordered_map<uint64_t, RemotePhysicsLink*> links_;  // by Key(worker, handle)
  uint32_t next_handle_ = 0;
};

}  // namespace edgephys
