// The two halves of the reliable-ordered channel (connection.h), kept apart from packet
// framing so they can be reasoned about and tested on their own.
//
// ReliableSender: owns the queued message bytes, cuts each message into units of at most
// kMaxReliableUnitSize bytes numbered with consecutive u16 unit ids, and tracks which units
// are acknowledged. Only the kReliableWindow units starting at the oldest unacknowledged one
// may be on the wire. Memory: the queued bytes (bounded by max_pending_bytes) plus one small
// record per unit; buffers grow to their steady-state size and are then reused.
//
// ReliableReceiver: accepts units whose id lies in [next expected, next expected + window),
// buffers out-of-order ones, drops duplicates and hands whole messages to the handler in send
// order, exactly once. Memory is bounded by kReliableWindow * kMaxReliableUnitSize buffered
// bytes plus max_message_size for the message being reassembled.
//
// Thread-safety: none (owned by one Connection). Cost: O(unit size) per unit.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "protocol/connection.h"
#include "protocol/ring_queue.h"
#include "protocol/status.h"

namespace edgephys {

// One unit as carried in a reliable chunk (flags bit0 = last unit of its message).
struct ReliableUnitView {
  uint16_t id = 0;
  bool last = false;
  std::span<const uint8_t> data;
};

class ReliableSender {
 public:
  ReliableSender(size_t max_message_size, size_t max_pending_bytes);

  // Queues a message. Errors: kInvalidArgument (empty), kTooLarge, kQueueFull.
  Status Queue(std::span<const uint8_t> message);

  // Units that may be sent now: the first min(queued units, kReliableWindow) ones. Index 0 is
  // the oldest unacknowledged unit. Indices are invalidated by Ack().
  size_t sendable_count() const;
  // True when unit `index` is unacknowledged and was never sent or was last sent at least
  // `resend_timeout_s` before `now`.
  bool IsDue(size_t index, double now, double resend_timeout_s) const;
  ReliableUnitView View(size_t index) const;
  // True when unit `index` went out at least once.
  bool IsSent(size_t index) const { return units_[index].sent; }
  // Records a transmission of unit `index`; returns true when it was a resend.
  bool MarkSent(size_t index, double now);

  // The packet that carried unit `unit_id` was acknowledged. Unknown or already acknowledged
  // ids are ignored.
  void Ack(uint16_t unit_id);

  // Bytes queued or sent but not yet acknowledged.
  size_t pending_bytes() const { return pending_bytes_; }
  // Absolute stream offsets: where the next queued byte will go, and the end of the longest
  // acknowledged prefix (every byte before it has been acknowledged).
  uint64_t queued_end() const { return bytes_base_ + bytes_.size(); }
  uint64_t acked_end() const { return bytes_head_; }
  size_t queued_units() const { return units_.size(); }
  // Units queued and never sent (in the window or beyond it).
  size_t unsent_units() const { return unsent_units_; }
  // The earliest last_sent of the first `scan` sendable units that are sent and unacknowledged;
  // +infinity if none. O(scan).
  double OldestInFlight(size_t scan) const;

 private:
  struct Unit {
    uint64_t offset = 0;  // absolute stream offset of the first byte
    uint16_t size = 0;
    bool last = false;
    bool acked = false;
    bool sent = false;
    double last_sent = 0;
  };
  void Compact();

  size_t max_message_size_;
  size_t max_pending_bytes_;
  size_t pending_bytes_ = 0;
  size_t unsent_units_ = 0;
  uint16_t base_id_ = 0;  // id of units_[0]
  RingQueue<Unit> units_;
  std::vector<uint8_t> bytes_;  // stream bytes from absolute offset bytes_base_
  uint64_t bytes_base_ = 0;     // absolute offset of bytes_[0]
  uint64_t bytes_head_ = 0;     // absolute offset of the first byte still needed
};

class ReliableReceiver {
 public:
  explicit ReliableReceiver(size_t max_message_size);

  enum class Placement { kInWindow, kDuplicate, kOutsideWindow };
  // Where unit `id` falls relative to the receive window. Does not change state.
  Placement Classify(uint16_t id) const;

  // Accepts one unit, delivering any messages it completes to `handler`. Counts duplicate
  // units in *duplicates and delivered messages in *delivered. Returns kTooLarge when a
  // message would exceed max_message_size (the caller then treats the peer as broken; the
  // receiver must not be used further), kResourceExhausted for a unit outside the window.
  Status Receive(const ReliableUnitView& unit, ConnectionHandler& handler, uint64_t* delivered,
                 uint64_t* duplicates);

  size_t buffered_bytes() const { return buffered_bytes_; }

 private:
  struct Slot {
    bool present = false;
    bool last = false;
    std::vector<uint8_t> data;  // capacity kept for reuse
  };
  Status Append(std::span<const uint8_t> data, bool last, ConnectionHandler& handler,
                uint64_t* delivered);

  size_t max_message_size_;
  uint16_t next_id_ = 0;     // next unit to deliver
  std::vector<Slot> slots_;  // kReliableWindow slots, allocated on first out-of-order unit
  size_t buffered_bytes_ = 0;
  std::vector<uint8_t> message_;  // the message being reassembled
};

}  // namespace edgephys
