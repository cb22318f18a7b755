// Asynchronous embedded PhyS: rooms' RoomPhysics stepped on a small fixed set of physics
// threads, off the relay's I/O path (issue "Relay throughput", item 3). A room whose step takes
// 400 ms no longer stops the handshakes, acks, resends and ticks of every other room.
//
// How a room runs (EmbeddedPhysicsLink, relay/physics_link.h, is the relay's face of it):
//  * The relay's thread posts commands (Add/Remove/Drive/RequestGrab/Release/Restore) into the
//    room's inbox and, once per update, Advance(now): it sets the time to step towards, takes
//    whatever steps have finished since the last call and, if a fixed step is due or commands
//    wait, queues the room for a physics thread. It never waits for a step: the room's mutex
//    is held by the physics thread only to swap buffers, never while stepping.
//  * A physics thread takes the room from the pool's FIFO, applies the commands in order,
//    steps towards the latest target and publishes the output; if more is due, the room goes
//    to the back of the FIFO (rooms share threads fairly, a heavy room holds one thread for
//    one of its iterations at a time). A room is run by at most one thread at a time, so its
//    Bullet world (built without BT_THREADSAFE) needs no lock; separate worlds share nothing.
//  * A room slower than real time simulates slower: when its steps cost more wall time than
//    they simulate, each iteration runs one step and the backlog is dropped (no catch-up
//    bursts); otherwise up to max_substeps steps catch up with scheduling jitter, as
//    PhysicsWorld::Advance does.
//
// Thread-safety: AsyncPhysicsRoom's relay-side methods (Post, Advance, Close) from one thread at
// a time (the link owner's); everything else is internal to the pool. Cost per relay update and
// room: one uncontended mutex lock, plus a condition-variable notify when the room is queued
// (about once per fixed step). Commands are not allocated in steady state (the inbox is
// double-buffered, consecutive drives of one entity coalesce); Add copies its container.
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <limits>
#include <memory>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "edgephys/schema/container_generated.h"
#include "physics_backend/physics_world.h"
#include "physics_backend/room_physics.h"

namespace edgephys {

// One input for a room's PhyS, in the order the relay issued it.
struct PhysicsCommand {
  enum class Kind : uint8_t { kAdd, kRemove, kDrive, kGrab, kRelease, kRestore, kRestoreNodes };
  Kind kind = Kind::kRemove;
  PhysicsRole role = PhysicsRole::kNone;  // kAdd
  bool force = false;                     // kGrab: skip the hover check (failover)
  uint32_t id = 0;                        // the entity
  uint32_t hand = 0;                      // kGrab
  EntityState state{};                    // kDrive, kRestore
  double time = 0;                        // kDrive: when the pose holds (RoomPhysics::Drive)
  Vec3f linear{}, angular{};              // kRestore
  std::vector<Vec3f> nodes;               // kRestoreNodes: every particle of the soft body
  flatbuffers::DetachedBuffer container;  // kAdd: a finished buffer whose root is a Container
};

// The fixed-step bookkeeping of RoomPhysics::Advance and PhysicsWorld::Advance (the time last
// fed and the accumulator), replayed from their inputs and step counts, so the relay knows
// when the next step is due without asking the world.
struct StepClock {
  double fed = 0;  // the last `now` given to RoomPhysics::Advance
  double acc = 0;  // PhysicsWorld's accumulator after that call
  // RoomPhysics::Advance(now) ran `steps` fixed steps of `fixed_dt`.
  void Record(double now, int steps, float fixed_dt);
  // The earliest `now` at which RoomPhysics::Advance(now) runs a step.
  double next_due(float fixed_dt) const { return fed + (fixed_dt - acc); }
};

// Simulated seconds per second of the relay's clock, over windows of about a second.
class RealtimeMeter {
 public:
  static constexpr double kWindowSeconds = 1.0;
  explicit RealtimeMeter(double now) : start_(now) {}
  // `simulated` seconds of PhyS were delivered at `now`.
  void Record(double now, double simulated);
  // The last completed window's factor; NaN before the first window completes.
  double value() const { return value_; }

 private:
  double start_;
  double simulated_ = 0;
  double value_ = std::numeric_limits<double>::quiet_NaN();
};

// Merges `from` into `into` as if one call had produced both, `from` being the later: moved
// bodies and soft bodies keep their latest state (one entry per entity), events and grab
// answers are appended in order, steps and step_seconds add up. `index` is scratch (entity id ->
// position in into->moved), valid across calls for the same `into` until it is cleared.
void MergeStepOutput(RoomPhysics::StepOutput* into, RoomPhysics::StepOutput* from,
                     std::unordered_map<uint32_t, size_t>* index);

// Add()'s answer decided on the relay's thread without the room's world (which a physics thread
// may be stepping): RoomPhysics::Add's rules (mirrored dynamic bodies become kinematic; soft
// bodies must be simulated), the component checks of an empty PhysicsWorld, and the checks
// against the room's entities (ids, parents, joint partners), which it keeps. Accepts and
// refuses exactly what the world would; the InvalidReason in a refusal's detail can differ
// only for a container with a bad joint partner and another fault checked after it.
class PhysicsAdmission {
 public:
  explicit PhysicsAdmission(const physics::PhysicsConfig& config) : config_(config) {}
  // An entity the world accepted (synchronously).
  void Added(const schema::Container& c, PhysicsRole role);
  // RoomPhysics::Add's verdict, with the Status EmbeddedPhysicsLink returns; when accepted, the
  // entity is recorded and `*command` is the kAdd to post (the container as the world builds it).
  Status Admit(const schema::Container& c, PhysicsRole role, PhysicsCommand* command);
  void Removed(uint32_t id) { known_.erase(id); }
  // The role an entity was added in; kNone if not in the world.
  PhysicsRole RoleOf(uint32_t id) const;
  // Refusals the world would have counted in PhysicsCounters::rejected_containers.
  uint64_t rejected() const { return rejected_; }

 private:
  struct Known {
    PhysicsRole role = PhysicsRole::kNone;
    bool has_body = false;  // a Bullet rigid body (a joint may connect to it)
  };
  physics::InvalidReason Check(const schema::Container& added, schema::ContainerT* copy);
  physics::PhysicsConfig config_;
  std::unique_ptr<physics::PhysicsWorld> validator_;  // empty, never stepped; made on first use
  std::unordered_map<uint32_t, Known> known_;
  uint64_t rejected_ = 0;
};

class AsyncPhysicsPool;

// One room's PhyS on the pool. Created by AsyncPhysicsPool::Adopt, owned by the pool, freed on a
// physics thread after Close().
class AsyncPhysicsRoom {
 public:
  using StepOutput = RoomPhysics::StepOutput;
  using Outputs = std::vector<std::unique_ptr<StepOutput>>;
  // Most finished outputs held for the relay: beyond, the room waits until they are taken.
  static constexpr size_t kMaxFinished = 4;

  AsyncPhysicsRoom(const AsyncPhysicsRoom&) = delete;
  AsyncPhysicsRoom& operator=(const AsyncPhysicsRoom&) = delete;

  // --- Relay side ---------------------------------------------------------------------------
  // Queues a command; applied before the next step, after every command posted before it. A
  // drive replaces the queued drive of the same entity if no other command came in between.
  void Post(PhysicsCommand&& command);
  // Sets the time to step towards, appends the outputs finished since the last call to
  // `*finished` (oldest first), gives back `*used` (outputs taken earlier, for reuse) and copies
  // the world's counters as of its last step into `*counters`. Queues the room when a step is
  // due or commands wait. Never waits for a step.
  void Advance(double now, Outputs* finished, Outputs* used, physics::PhysicsCounters* counters);
  // The link is gone: queued commands are dropped and the room is freed on a physics thread
  // (after its current iteration, if one is running). The caller must not use it afterwards.
  void Close();

 private:
  friend class AsyncPhysicsPool;
  enum class Run { kIdle, kRequeue, kClosed };
  AsyncPhysicsRoom(AsyncPhysicsPool* pool, std::unique_ptr<RoomPhysics> physics,
                   const physics::PhysicsConfig& config, const StepClock& clock);
  // On a physics thread: applies the inbox, steps towards the target, publishes the output.
  Run RunOnce();
  void Apply(PhysicsCommand& command);
  bool WantsRun() const;  // mu_ held

  AsyncPhysicsPool* const pool_;
  const float fixed_dt_;
  const int max_substeps_;

  std::mutex mu_;
  // Guarded by mu_.
  std::vector<PhysicsCommand> inbox_;
  size_t drive_run_ = 0;      // inbox_[drive_run_..] are all drives (coalescing window)
  double target_;             // relay clock
  double next_due_;           // relay clock: the next fixed step is due then
  Outputs finished_;          // finished, not yet taken by the relay
  Outputs spare_;             // emptied outputs for reuse
  physics::PhysicsCounters counters_{};
  bool scheduled_ = false;    // queued in the pool's FIFO or running on a thread
  bool closed_ = false;

  // The running thread's only (at most one at a time; handed over through the pool's mutex).
  std::unique_ptr<RoomPhysics> physics_;
  std::vector<PhysicsCommand> work_;
  StepClock clock_;           // in simulation time
  double offset_ = 0;         // relay clock - simulation time (grows with dropped backlog)
  bool slow_ = false;         // the last steps cost more wall time than they simulated
};

// The physics threads. Rooms are adopted from EmbeddedPhysicsLinks switching to asynchronous
// stepping; every room must be closed (its link destroyed) before the pool is destroyed, which
// stops the threads after their current iteration, joins them and frees what is left.
//
// `nice` > 0 (Linux): each physics thread lowers its own scheduling priority by that much
// (setpriority on the thread, capped at 19) when it starts, so that when the machine's cores
// are all busy the relay's I/O thread (and anything else at normal priority) runs first and a
// heavy room simulates slower instead of delaying other rooms' packets (`edgephys-loadgen
// isolation`). Lowering priority needs no privilege; if it fails the thread runs at normal
// priority and a warning is logged. 0: the threads keep the process's priority.
//
// `idle` (Linux): each physics thread puts itself in SCHED_IDLE instead (`nice` is then
// ignored): it runs only on a core that has no normal-priority thread to run, where niceness
// 19 still takes a ~1.5 % weighted share and waits out wake-up granularity. On 2 shared cores it
// brought a neighbouring room's socket p99 ratio from 1.28x to 1.09x (`edgephys-loadgen
// isolation`). Cost: on a machine whose cores are always busy with other work,
// PhyS rooms make no progress at all (their real-time factor falls towards 0); the relay loop
// itself is unaffected.
class AsyncPhysicsPool {
 public:
  explicit AsyncPhysicsPool(size_t threads, int nice = 0, bool idle = false);
  ~AsyncPhysicsPool();
  AsyncPhysicsPool(const AsyncPhysicsPool&) = delete;
  AsyncPhysicsPool& operator=(const AsyncPhysicsPool&) = delete;

  // Takes over `physics`, whose RoomPhysics::Advance calls so far are summarised by `clock`.
  AsyncPhysicsRoom* Adopt(std::unique_ptr<RoomPhysics> physics,
                          const physics::PhysicsConfig& config, const StepClock& clock);
  size_t threads() const { return threads_.size(); }
  // The niceness increment the threads asked for (0: none), whether they asked for SCHED_IDLE,
  // and how many got what they asked for.
  int nice() const { return nice_; }
  bool idle() const { return sched_idle_; }
  size_t threads_reniced() const { return reniced_.load(); }
  // Blocks until no room is queued or running (every room has stepped up to its last target
  // and applied its commands). For tests.
  void WaitIdle();

 private:
  friend class AsyncPhysicsRoom;
  void Schedule(AsyncPhysicsRoom* room);  // the room's scheduled_ was just set
  void ThreadLoop();

  int nice_ = 0;
  bool sched_idle_ = false;
  std::atomic<size_t> reniced_{0};
  std::mutex mu_;
  std::condition_variable wake_, idle_;
  std::deque<AsyncPhysicsRoom*> ready_;
  std::unordered_set<AsyncPhysicsRoom*> rooms_;  // every room not yet freed
  size_t running_ = 0;
  bool stop_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace edgephys
