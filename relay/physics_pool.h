// PhysicsPool: steps the rooms' embedded PhyS worlds in parallel, fork-join, once per relay
// update. Each world is touched by exactly one thread per Run() and by the relay's thread
// only between runs, so Bullet (built without BT_THREADSAFE) needs no locking; the pool's
// mutex is taken twice per Run(), never per packet.
//
// Thread-safety: Run() from one thread at a time (the relay's). Cost: a wake-up of the pool
// threads per Run(); work is split dynamically (an atomic index).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <functional>
#include <mutex>
#include <thread>
#include <vector>

namespace edgephys {

class PhysicsPool {
 public:
  // `threads` workers in total, the caller included (1: everything runs on the caller).
  explicit PhysicsPool(size_t threads);
  ~PhysicsPool();
  PhysicsPool(const PhysicsPool&) = delete;
  PhysicsPool& operator=(const PhysicsPool&) = delete;

  // Calls fn(i) for every i in [0, n), spread over the pool; returns when all are done.
  void Run(size_t n, const std::function<void(size_t)>& fn);
  size_t threads() const { return workers_.size() + 1; }

 private:
  void WorkerLoop();
  void Drain();
  std::vector<std::thread> workers_;
  std::mutex mutex_;
  std::condition_variable start_, done_;
  const std::function<void(size_t)>* fn_ = nullptr;
  size_t n_ = 0;
  std::atomic<size_t> next_{0};
  size_t busy_ = 0;
  uint64_t generation_ = 0;
  bool stop_ = false;
};

}  // namespace edgephys
