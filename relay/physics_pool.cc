#include "relay/physics_pool.h"

#include "relay/async_physics.h"

namespace edgephys {

PhysicsPool::PhysicsPool(size_t threads, int physics_nice, bool physics_idle)
    : physics_nice_(physics_nice), physics_idle_(physics_idle) {
  for (size_t i = 1; i < threads; ++i) workers_.emplace_back([this] { WorkerLoop(); });
}

AsyncPhysicsPool* PhysicsPool::async_physics() {
  if (workers_.empty()) return nullptr;
  if (async_ == nullptr) async_ = std::make_unique<AsyncPhysicsPool>(workers_.size(), physics_nice_, physics_idle_);
  return async_.get();
}

PhysicsPool::~PhysicsPool() {
  async_.reset();  // stops and joins the physics threads
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  start_.notify_all();
  for (std::thread& t : workers_) t.join();
}

void PhysicsPool::Drain() {
  for (size_t i = next_.fetch_add(1); i < n_; i = next_.fetch_add(1)) (*fn_)(i);
}

void PhysicsPool::Run(size_t n, const std::function<void(size_t)>& fn) {
  if (n == 0) return;
  if (workers_.empty() || n == 1) {
    for (size_t i = 0; i < n; ++i) fn(i);
    return;
  }
  {
    std::lock_guard<std::mutex> lock(mutex_);
    fn_ = &fn;
    n_ = n;
    next_.store(0);
    open_ = true;
    ++generation_;
  }
  start_.notify_all();
  Drain();
  // Every index is taken. Close this run to workers that have not joined it yet (not woken, or
  // woken but not scheduled: on a machine whose cores are busy, waiting for them would make the
  // relay's loop wait for a time slice), and wait only for those still running an index.
  std::unique_lock<std::mutex> lock(mutex_);
  open_ = false;
  done_.wait(lock, [this] { return busy_ == 0; });
  fn_ = nullptr;
}

void PhysicsPool::WorkerLoop() {
  uint64_t seen = 0;
  for (;;) {
    bool hook = false;
    {
      std::unique_lock<std::mutex> lock(mutex_);
      start_.wait(lock, [&] { return stop_ || generation_ != seen; });
      if (stop_) return;
      seen = generation_;
      hook = static_cast<bool>(wake_hook_);
    }
    if (hook) wake_hook_();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (stop_) return;
      if (!open_ || generation_ != seen) {  // the caller finished run `seen` alone
        ++late_wakeups_;
        continue;
      }
      ++busy_;
      ++joined_;
    }
    Drain();
    {
      std::lock_guard<std::mutex> lock(mutex_);
      if (--busy_ == 0) done_.notify_one();
    }
  }
}

void PhysicsPool::SetWorkerWakeHookForTesting(std::function<void()> hook) {
  std::lock_guard<std::mutex> lock(mutex_);
  wake_hook_ = std::move(hook);
}

uint64_t PhysicsPool::late_wakeups() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return late_wakeups_;
}

uint64_t PhysicsPool::joined() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return joined_;
}

}  // namespace edgephys
