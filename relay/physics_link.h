// PhysicsLink: where a room's PhyS runs, as the relay sees it. Two implementations:
//  * EmbeddedPhysicsLink: a RoomPhysics in the relay process (the default). Synchronous until
//    RunOn(pool): then the world steps on the pool's physics threads (relay/async_physics.h)
//    and the relay's thread only hands commands over and picks finished steps up.
//  * RemotePhysicsLink: a room handle on an attached edgephys-phys worker; commands go out as
//    Worker* control messages, results come back asynchronously (ReceiveResult/ReceiveStates)
//    and are handed out by the next Advance().
// The relay keeps every entity's container, latest state and velocities, so when a worker
// dies or stalls it rebuilds the room on another link without losing an entity (failover).
//
// Thread-safety: every method from the relay's thread. Cost: embedded synchronous Advance()
// is the physics step; asynchronous Advance() takes a mutex and merges finished outputs
// (O(moved bodies) only when several finished since the last call); Add() copies and checks
// the container; remote calls serialise a small message each.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "edgephys/schema/control_generated.h"
#include "physics_backend/room_physics.h"
#include "physics_backend/worker_protocol.h"
#include "protocol/connection.h"
#include "relay/async_physics.h"

namespace edgephys {

// Where a RemotePhysicsLink is registered for routing (the relay's WorkerDirectory); told when
// the link goes.
class PhysicsLinkRegistry {
 public:
  virtual ~PhysicsLinkRegistry() = default;
  virtual void Unregister(uint32_t worker_id, uint32_t handle) = 0;
};

class PhysicsLink {
 public:
  using StepOutput = RoomPhysics::StepOutput;
  virtual ~PhysicsLink() = default;
  // Validates and adds an entity (same rules embedded or remote). kInvalidArgument with a
  // detail naming the problem when the components are refused.
  virtual Status Add(const schema::Container& c, PhysicsRole role) = 0;
  virtual void Remove(uint32_t id) = 0;
  // `time`: when the pose holds, on the relay's clock (its arrival). PhyS keeps it for the
  // velocity a released object leaves with (RoomPhysics::Drive); a remote link sends it with
  // the pose (WorkerDrive::times).
  virtual void Drive(uint32_t id, const EntityState& state, double time) = 0;
  // The answer arrives in a later Advance() output. `force` skips the hover check (failover).
  virtual void RequestGrab(uint32_t entity, uint32_t hand, bool force = false) = 0;
  virtual void Release(uint32_t entity) = 0;
  virtual void Restore(uint32_t id, const EntityState& state, const Vec3f& linear,
                       const Vec3f& angular) = 0;
  // Restores a soft body's deformed particles (every one, room frame) after Add (failover);
  // remote links send them in messages of at most kRestoreNodesPerMessage particles.
  virtual void RestoreSoftBody(uint32_t id, std::span<const Vec3f> nodes) = 0;
  static constexpr size_t kRestoreNodesPerMessage = 4096;
  // Steps (embedded) or collects what the worker sent (remote) up to `now`.
  virtual void Advance(double now, StepOutput* out) = 0;
  // False when the link cannot go on (its worker disconnected or stopped answering).
  virtual bool Healthy(double now) const = 0;
  // Connection id of the worker session, 0 for embedded.
  virtual uint32_t worker() const = 0;
  virtual physics::PhysicsCounters counters() const = 0;
  // The link is being replaced after a failure: send nothing more (not even a goodbye).
  virtual void Detach() {}
  // Simulated seconds per second of the relay's clock over the last completed window of about
  // a second (RealtimeMeter): 1 keeps up, below 1 the room simulates slower than real time.
  // NaN while unknown (no window completed yet; remote links, whose steps are not counted).
  virtual double realtime_factor() const { return std::numeric_limits<double>::quiet_NaN(); }
  // Embedded links: from now on the world steps on `pool`'s threads and Advance() never waits
  // for a step. `pool` must outlive the link. No-op for remote links and when already there.
  virtual void RunOn(AsyncPhysicsPool* pool) { (void)pool; }
};

class EmbeddedPhysicsLink final : public PhysicsLink {
 public:
  EmbeddedPhysicsLink(const physics::PhysicsConfig& config, double now);
  // Asynchronous: the room is closed without waiting; a physics thread frees it (after the
  // step it may be running).
  ~EmbeddedPhysicsLink() override;
  EmbeddedPhysicsLink(const EmbeddedPhysicsLink&) = delete;
  EmbeddedPhysicsLink& operator=(const EmbeddedPhysicsLink&) = delete;

  // Synchronous: RoomPhysics' calls. Asynchronous: Add is decided at once (PhysicsAdmission),
  // the commands are queued in order and applied before the next step.
  Status Add(const schema::Container& c, PhysicsRole role) override;
  void Remove(uint32_t id) override;
  void Drive(uint32_t id, const EntityState& s, double time) override;
  void RequestGrab(uint32_t entity, uint32_t hand, bool force) override;
  void Release(uint32_t entity) override;
  void Restore(uint32_t id, const EntityState& s, const Vec3f& l, const Vec3f& a) override;
  void RestoreSoftBody(uint32_t id, std::span<const Vec3f> nodes) override;
  // Synchronous: runs the steps due by `now`. Asynchronous: the steps finished since the last
  // call, merged into one output (MergeStepOutput; empty if none), and `now` as the new target.
  void Advance(double now, StepOutput* out) override;
  bool Healthy(double) const override { return true; }
  uint32_t worker() const override { return 0; }
  // Asynchronous: as of the last step finished before the last Advance().
  physics::PhysicsCounters counters() const override;
  double realtime_factor() const override { return meter_.value(); }
  void RunOn(AsyncPhysicsPool* pool) override;
  bool asynchronous() const { return room_ != nullptr; }

 private:
  const physics::PhysicsConfig config_;
  std::unique_ptr<RoomPhysics> physics_;  // synchronous; null once on a pool
  StepClock clock_;                       // synchronous: physics_'s step bookkeeping
  PhysicsAdmission admission_;            // the world's entities, as the relay knows them
  AsyncPhysicsRoom* room_ = nullptr;      // asynchronous: the pool's (closed when destroyed)
  AsyncPhysicsRoom::Outputs finished_, used_;
  std::unordered_map<uint32_t, size_t> merge_index_;
  physics::PhysicsCounters counters_{};   // asynchronous: the last copy
  RealtimeMeter meter_;
};

// Sends reliable control messages to a worker; implemented by the relay's worker session.
class WorkerChannel {
 public:
  virtual ~WorkerChannel() = default;
  virtual bool SendToWorker(std::span<const uint8_t> message) = 0;  // false: link broken
  virtual bool WorkerConnected() const = 0;
};

class RemotePhysicsLink final : public PhysicsLink {
 public:
  // `channel` (not owned) must outlive the link or be detached with Detach().
  RemotePhysicsLink(WorkerChannel* channel, uint32_t worker_id, uint32_t room_handle,
                    const physics::PhysicsConfig& config, double now);
  ~RemotePhysicsLink() override;

  Status Add(const schema::Container& c, PhysicsRole role) override;
  void Remove(uint32_t id) override;
  void Drive(uint32_t id, const EntityState& state, double time) override;
  void RequestGrab(uint32_t entity, uint32_t hand, bool force) override;
  void Release(uint32_t entity) override;
  void Restore(uint32_t id, const EntityState& s, const Vec3f& l, const Vec3f& a) override;
  void RestoreSoftBody(uint32_t id, std::span<const Vec3f> nodes) override;
  void Advance(double now, StepOutput* out) override;
  bool Healthy(double now) const override;
  uint32_t worker() const override { return worker_id_; }
  physics::PhysicsCounters counters() const override { return counters_; }

  // From the worker: a WorkerResult for this room, and a state payload (format 6 or 8).
  void ReceiveResult(const schema::WorkerResult& result, double now);
  void ReceiveStates(std::span<const uint8_t> payload, double now);
  // The worker is gone: stop sending.
  void Detach() override { channel_ = nullptr; }
  uint32_t handle() const { return handle_; }
  // The registry that routes this link's messages (told on destruction); may be null.
  void set_registry(PhysicsLinkRegistry* registry) { registry_ = registry; }

 private:
  void Send(flatbuffers::FlatBufferBuilder& fbb);
  WorkerChannel* channel_;
  PhysicsLinkRegistry* registry_ = nullptr;
  uint32_t worker_id_;
  uint32_t handle_;
  // The worker's entities as the relay knows them, and the same checks an embedded world
  // makes (ids, parents and joint partners against these, every component of a child too).
  PhysicsAdmission admission_;
  StepOutput pending_;
  std::vector<schema::Pose> drives_;  // batched per Advance
  std::vector<double> drive_times_;   // when each holds (Drive's time), parallel to drives_
  double last_heard_;
  double stall_timeout_s_ = 0.75;  // a worker reports every 0.2 s; silence beyond: stalled
  physics::PhysicsCounters counters_{};
  bool broken_ = false;
};

}  // namespace edgephys
