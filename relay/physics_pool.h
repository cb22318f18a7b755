// PhysicsPool: the relay's helper threads. Two kinds:
//  * Fork-join (Run): the relay's replication ticks, receivers in parallel, once per update;
//    with synchronous PhyS (one thread in all) also the embedded worlds' steps. The pool's
//    mutex is taken twice per Run(), never per packet.
//  * Asynchronous PhyS (async_physics()): threads() - 1 physics threads, started on first use,
//    that step embedded worlds off the relay's loop (relay/async_physics.h). With threads() == 1
//    there are none: PhyS steps synchronously on the relay's thread, deterministically (tests
//    with a fake clock, fuzzing).
// A world is touched by one thread at a time either way, so Bullet (built without
// BT_THREADSAFE) needs no locking.
//
// Thread-safety: Run() and async_physics() from one thread at a time (the relay's). Cost: a
// wake-up of the pool threads per Run(); work is split dynamically (an atomic index).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

namespace edgephys {

class AsyncPhysicsPool;

class PhysicsPool {
 public:
  // `threads` workers in total, the caller included (1: everything runs on the caller).
  // `physics_nice`, `physics_idle`: passed to the asynchronous PhyS threads (AsyncPhysicsPool);
  // the fork-join workers keep the caller's priority.
  explicit PhysicsPool(size_t threads, int physics_nice = 0, bool physics_idle = false);
  ~PhysicsPool();
  PhysicsPool(const PhysicsPool&) = delete;
  PhysicsPool& operator=(const PhysicsPool&) = delete;

  // Calls fn(i) for every i in [0, n), spread over the pool; returns when all are done. The
  // caller takes indices too, and waits only for workers that joined the run before it had
  // taken the last index: a worker not yet running (its core busy with PhyS or another
  // process) is not waited for, so the caller never waits for a time slice. Counted in
  // late_wakeups(); joined() counts the runs workers took part in (both for tests and profiles).
  void Run(size_t n, const std::function<void(size_t)>& fn);
  uint64_t late_wakeups() const;
  uint64_t joined() const;
  // Tests: each worker calls `hook` when woken for a run, before it may join it. Set before
  // any Run().
  void SetWorkerWakeHookForTesting(std::function<void()> hook);
  size_t threads() const { return workers_.size() + 1; }
  // The asynchronous PhyS threads (threads() - 1 of them, started on the first call); null when
  // threads() == 1 (PhyS is then stepped synchronously). Every link running on them must be
  // destroyed before this pool.
  AsyncPhysicsPool* async_physics();

 private:
  void WorkerLoop();
  void Drain();
  int physics_nice_ = 0;
  bool physics_idle_ = false;
  std::vector<std::thread> workers_;
  mutable std::mutex mutex_;
  std::condition_variable start_, done_;
  const std::function<void(size_t)>* fn_ = nullptr;
  size_t n_ = 0;
  std::atomic<size_t> next_{0};
  size_t busy_ = 0;       // workers in the current run
  bool open_ = false;     // the current run still takes workers
  uint64_t late_wakeups_ = 0, joined_ = 0;
  std::function<void()> wake_hook_;
  uint64_t generation_ = 0;
  bool stop_ = false;
  std::unique_ptr<AsyncPhysicsPool> async_;
};

}  // namespace edgephys
