// DatagramDelayQueue: datagrams held until they are due, released in order of due time. The
// queue of NetworkSimulator (protocol/network_simulator.h) and of udp_impair's ImpairSchedule
// (tests/netem/impair_schedule.h): each decides a datagram's delay, this holds it.
//
// Thread-safety: none. Cost: O(log queued) per Push/Pop plus the copy; holds at most max_items
// datagrams and max_bytes payload bytes (a Push beyond either is refused); buffers are reused,
// so steady-state operation does not allocate.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

namespace edgephys {

// A bounded min-queue of datagrams by due time (ties: push order). `Tag` is the caller's routing
// key, copied in with each datagram (NetworkSimulator: the destination endpoint; udp_impair:
// client slot and generation). Buffers are reused once allocated.
template <typename Tag>
class DatagramDelayQueue {
 public:
  DatagramDelayQueue(size_t max_items, size_t max_bytes)
      : max_items_(max_items), max_bytes_(max_bytes) {}

  // False (and nothing queued) when max_items or max_bytes would be exceeded.
  bool Push(double due, const Tag& tag, std::span<const uint8_t> data) {
    if (heap_.size() >= max_items_ || bytes_ + data.size() > max_bytes_) return false;
    size_t index;
    if (!free_.empty()) {
      index = free_.back();
      free_.pop_back();
    } else {
      index = items_.size();
      items_.emplace_back();
    }
    Item& item = items_[index];
    item.due = due;
    item.order = next_order_++;
    item.tag = tag;
    item.data.assign(data.begin(), data.end());
    bytes_ += data.size();
    heap_.push_back(index);
    std::push_heap(heap_.begin(), heap_.end(), Later{this});
    return true;
  }

  bool empty() const { return heap_.empty(); }
  size_t size() const { return heap_.size(); }
  size_t bytes() const { return bytes_; }
  // Due time of the next datagram; only when !empty().
  double next_due() const { return items_[heap_.front()].due; }

  // Calls fn(const Tag&, span<const uint8_t>, due) for every datagram due at `now`, in due order.
  // Returns how many were released.
  template <typename Fn>
  size_t PopDue(double now, Fn&& fn) {
    size_t n = 0;
    while (!heap_.empty() && items_[heap_.front()].due <= now) {
      std::pop_heap(heap_.begin(), heap_.end(), Later{this});
      const size_t index = heap_.back();
      heap_.pop_back();
      Item& item = items_[index];
      bytes_ -= item.data.size();
      fn(item.tag, std::span<const uint8_t>(item.data), item.due);
      free_.push_back(index);
      ++n;
    }
    return n;
  }

 private:
  struct Item {
    double due = 0;
    uint64_t order = 0;
    Tag tag{};
    std::vector<uint8_t> data;
  };
  struct Later {
    const DatagramDelayQueue* q;
    bool operator()(size_t a, size_t b) const {
      const Item& x = q->items_[a];
      const Item& y = q->items_[b];
      return x.due > y.due || (x.due == y.due && x.order > y.order);
    }
  };

  size_t max_items_;
  size_t max_bytes_;
  size_t bytes_ = 0;
  uint64_t next_order_ = 0;
  std::vector<Item> items_;
  std::vector<size_t> free_;
  std::vector<size_t> heap_;
};

}  // namespace edgephys
