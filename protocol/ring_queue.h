// RingQueue<T>: a FIFO over a power-of-two ring that grows by doubling and never shrinks, so
// a queue that has reached its steady-state size pushes and pops without allocating.
// Elements are indexed from the front (0 = oldest). T must be default-constructible and
// movable; popped slots keep their (moved-from or stale) values until reused.
// Thread-safety: none. Cost: push/pop/index O(1); growth O(size), amortised O(1).
#pragma once

#include <cassert>
#include <cstddef>
#include <utility>
#include <vector>

namespace edgephys {

template <typename T>
class RingQueue {
 public:
  RingQueue() = default;
  explicit RingQueue(size_t initial_capacity) { Reserve(initial_capacity); }

  size_t size() const { return size_; }
  bool empty() const { return size_ == 0; }
  size_t capacity() const { return slots_.size(); }

  T& operator[](size_t i) {
    assert(i < size_);
    return slots_[(head_ + i) & (slots_.size() - 1)];
  }
  const T& operator[](size_t i) const {
    assert(i < size_);
    return slots_[(head_ + i) & (slots_.size() - 1)];
  }
  T& front() { return (*this)[0]; }
  const T& front() const { return (*this)[0]; }

  void PushBack(T value) {
    if (size_ == slots_.size()) Reserve(size_ == 0 ? 16 : size_ * 2);
    slots_[(head_ + size_) & (slots_.size() - 1)] = std::move(value);
    ++size_;
  }

  // Appends the next slot as it stands (default-constructed, or a stale value from an earlier
  // use) and returns it, so the caller can overwrite it while reusing its buffers.
  T& PushBackSlot() {
    if (size_ == slots_.size()) Reserve(size_ == 0 ? 16 : size_ * 2);
    ++size_;
    return (*this)[size_ - 1];
  }

  void PopFront() {
    assert(size_ > 0);
    head_ = (head_ + 1) & (slots_.size() - 1);
    --size_;
  }

  void Clear() {
    head_ = 0;
    size_ = 0;
  }

  // Ensures room for `capacity` elements (rounded up to a power of two).
  void Reserve(size_t capacity) {
    if (capacity <= slots_.size()) return;
    size_t rounded = 16;
    while (rounded < capacity) rounded *= 2;
    std::vector<T> grown(rounded);
    for (size_t i = 0; i < size_; ++i) grown[i] = std::move((*this)[i]);
    slots_ = std::move(grown);
    head_ = 0;
  }

 private:
  std::vector<T> slots_;  // size is zero or a power of two
  size_t head_ = 0;
  size_t size_ = 0;
};

}  // namespace edgephys
