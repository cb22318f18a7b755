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
// order, exactly once. Memory: held_bytes() counts every byte it keeps allocated (the message
// being reassembled, the out-of-order units' buffers, the slot table) and stays under
// max(max_held_bytes, max_message_size) plus kReliableHeldSlack (connection.h): the caller asks
// Admits() before a packet's units and refuses the packet (unacknowledged, so the peer
// resends) when it says no. Out-of-order units are admitted only while the message so far plus
// the whole span up to the furthest of them, as full units, fits max_held_bytes; the unit
// that continues the stream is always admitted, so a peer within the protocol always
// progresses, only slower. Kept for reuse after delivery (so that steady traffic with loss
// allocates nothing): the slot table (32 KiB, from the first out-of-order unit on), up to
// kMaxSpareBuffers unit buffers, and a message buffer up to kRetainedMessageBytes.
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
  // Unit buffers (kMaxReliableUnitSize each) kept for reuse once their units are delivered.
  static constexpr size_t kMaxSpareBuffers = 64;
  // Capacity of the message buffer kept after a delivery; a larger one is freed.
  static constexpr size_t kRetainedMessageBytes = 16 * 1024;
  // The message buffer grows by at most this much at a time (bytes).
  static constexpr size_t kMessageGrowthStep = 64 * 1024;

  // `max_held_bytes`: bound on held_bytes() enforced through Admits() (the protocol's
  // promise: ConnectionConfig::max_held_reliable_bytes).
  ReliableReceiver(size_t max_message_size, size_t max_held_bytes);

  enum class Placement { kInWindow, kDuplicate, kOutsideWindow };
  // Where unit `id` falls relative to the receive window. Does not change state.
  Placement Classify(uint16_t id) const;

  // Accepts one unit, delivering any messages it completes to `handler`. Counts duplicate
  // units in *duplicates and delivered messages in *delivered. Returns kTooLarge when a
  // message would exceed max_message_size (the caller then treats the peer as broken; the
  // receiver must not be used further), kResourceExhausted for a unit outside the window.
  Status Receive(const ReliableUnitView& unit, ConnectionHandler& handler, uint64_t* delivered,
                 uint64_t* duplicates);

  // Whether the in-window units of one packet may be taken: true when they hold the next
  // expected unit (the stream progresses) or no out-of-order unit, or when the message so far,
  // the slot table and every unit up to the furthest out-of-order one (as full units) fit
  // max_held_bytes. Does not change state. O(units).
  bool Admits(std::span<const ReliableUnitView> units) const;

  // Out-of-order unit bytes waiting for the gap before them.
  size_t buffered_bytes() const { return buffered_bytes_; }
  // Every byte of reassembly memory this receiver keeps allocated (capacities, not sizes):
  // partial_bytes() plus the buffers kept for reuse and the slot table.
  size_t held_bytes() const;
  // Bytes allocated for messages in progress: the message being reassembled (once it has a
  // unit) and the buffers of out-of-order units waiting for a gap.
  size_t partial_bytes() const;

 private:
  struct Slot {
    bool present = false;
    bool last = false;
    std::vector<uint8_t> data;  // a buffer only while present
  };
  Status Append(std::span<const uint8_t> data, bool last, ConnectionHandler& handler,
                uint64_t* delivered);

  size_t max_message_size_;
  size_t max_held_bytes_;
  uint16_t next_id_ = 0;     // next unit to deliver
  std::vector<Slot> slots_;  // kReliableWindow slots, allocated on first out-of-order unit
  size_t buffered_bytes_ = 0;
  size_t in_use_capacity_ = 0;    // capacity of the present slots' buffers
  std::vector<std::vector<uint8_t>> spare_;  // delivered units' buffers, for reuse
  uint16_t buffered_end_ = 0;     // one past the furthest buffered unit (buffered_bytes_ > 0)
  std::vector<uint8_t> message_;  // the message being reassembled
};

}  // namespace edgephys
