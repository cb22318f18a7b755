// Book-keeping of packet sequences for one Connection (connection.h), both directions.
//
// SentPacketLog: what we sent, per sequence: when, whether it asked for an acknowledgement,
// whether it was acknowledged or deemed lost, and which reliable unit ids it carried (so an
// acknowledgement of the packet acknowledges them). Fixed-size rings: the last kCapacity
// packets and the last kUnitCapacity unit ids; older entries are overwritten and then simply
// unknown (their units are resent on timeout, which is always safe).
//
// ReceivedPacketLog: which of the peer's recent sequences we received, for duplicate
// detection and for the ack / ack_bits fields we send back.
//
// Thread-safety: none. Cost: O(1) per operation (O(32) for AckBits); no allocation after
// construction.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>

namespace edgephys {

class SentPacketLog {
 public:
  static constexpr size_t kCapacity = 1024;      // packets remembered
  static constexpr size_t kUnitCapacity = 8192;  // unit ids remembered across those packets

  struct Record {
    uint16_t sequence = 0;
    bool valid = false;
    bool acked = false;
    bool resolved = false;       // counted in the loss estimate (acked or deemed lost)
    bool ack_eliciting = false;  // carried chunks, so the peer acknowledges it promptly
    uint16_t unit_count = 0;
    uint64_t unit_begin = 0;  // absolute position in the unit-id ring
    double send_time = 0;
  };

  // Records packet `sequence`, replacing whatever occupied its slot. `units` may be empty.
  void Add(uint16_t sequence, double now, bool ack_eliciting, std::span<const uint16_t> units);

  // The record of `sequence`, or nullptr if it was never recorded or has been overwritten.
  Record* Find(uint16_t sequence);

  // The unit ids carried by `record`; empty if they have been overwritten since.
  std::span<const uint16_t> Units(const Record& record) const;

 private:
  std::array<Record, kCapacity> records_{};
  std::array<uint16_t, kUnitCapacity> units_{};
  uint64_t unit_next_ = 0;  // absolute position of the next unit id written
};

class ReceivedPacketLog {
 public:
  static constexpr size_t kCapacity = 1024;

  // True when `sequence` was already received, or is too old to tell (more than kCapacity
  // behind the newest): such packets are dropped as duplicates.
  bool IsDuplicate(uint16_t sequence) const;
  void Record(uint16_t sequence);

  // The newest sequence received; 0xFFFF (with empty AckBits) before the first packet.
  uint16_t ack() const { return any_ ? newest_ : 0xFFFF; }
  // Bit i set: sequence ack()-1-i was received.
  uint32_t AckBits() const;

 private:
  bool Has(uint16_t sequence) const;

  static constexpr uint32_t kValid = 1u << 16;
  std::array<uint32_t, kCapacity> seen_{};  // sequence | kValid, or 0
  uint16_t newest_ = 0;
  bool any_ = false;
};

}  // namespace edgephys
