// SpscRing<T>: a bounded, lock-free single-producer single-consumer queue of preallocated
// slots. The producer fills a slot in place (Claim, then Publish); the consumer reads it in
// place (Front, then Pop). No allocation after construction, no locks, no system calls.
//
// Thread-safety: exactly one producer thread (Claim/Publish) and one consumer thread
// (Front/Pop/Empty) at a time; either may be any thread. Publish() releases the slot's
// contents to the consumer's Front() (release/acquire on the indices).
// Cost: O(1) per operation; the indices sit on separate cache lines, and each side caches the
// other's index so it touches the shared line only when the ring looks full or empty.
#pragma once

#include <atomic>
#include <cstddef>
#include <new>
#include <vector>

namespace edgephys {

template <typename T>
class SpscRing {
 public:
  // Holds `capacity` elements, rounded up to a power of two (at least 2).
  explicit SpscRing(size_t capacity) {
    size_t n = 2;
    while (n < capacity) n <<= 1;
    slots_.resize(n);
    mask_ = n - 1;
  }
  SpscRing(const SpscRing&) = delete;
  SpscRing& operator=(const SpscRing&) = delete;

  size_t capacity() const { return slots_.size(); }

  // Producer: the next free slot to fill, or nullptr when the ring is full. The slot is not
  // visible to the consumer until Publish().
  T* Claim() {
    const size_t tail = tail_.load(std::memory_order_relaxed);
    if (tail - head_cache_ >= slots_.size()) {
      head_cache_ = head_.load(std::memory_order_acquire);
      if (tail - head_cache_ >= slots_.size()) return nullptr;
    }
    return &slots_[tail & mask_];
  }
  // Producer: makes the slot returned by the last Claim() visible to the consumer.
  void Publish() {
    tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release);
  }

  // Consumer: the oldest published slot, or nullptr when the ring is empty.
  T* Front() {
    const size_t head = head_.load(std::memory_order_relaxed);
    if (head == tail_cache_) {
      tail_cache_ = tail_.load(std::memory_order_acquire);
      if (head == tail_cache_) return nullptr;
    }
    return &slots_[head & mask_];
  }
  // Consumer: releases the slot returned by Front() back to the producer.
  void Pop() { head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }
  // Consumer: true when nothing is published (a fresh look at the producer's index).
  bool Empty() const {
    return head_.load(std::memory_order_relaxed) == tail_.load(std::memory_order_acquire);
  }

 private:
  static constexpr size_t kLine = 64;
  std::vector<T> slots_;
  size_t mask_ = 0;
  alignas(kLine) std::atomic<size_t> head_{0};  // written by the consumer
  size_t tail_cache_ = 0;                       // consumer's copy of tail_
  alignas(kLine) std::atomic<size_t> tail_{0};  // written by the producer
  size_t head_cache_ = 0;                       // producer's copy of head_
};

}  // namespace edgephys
