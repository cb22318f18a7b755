#include "protocol/packet_ledger.h"

#include <algorithm>

#include "protocol/sequence.h"

namespace edgephys {

void SentPacketLog::Add(uint16_t sequence, double now, bool ack_eliciting,
                        std::span<const uint16_t> units) {
  Record& record = records_[sequence % kCapacity];
  record = Record{};
  record.sequence = sequence;
  record.valid = true;
  record.ack_eliciting = ack_eliciting;
  record.send_time = now;
  size_t count = std::min(units.size(), kUnitCapacity);
  // Keep each packet's ids contiguous in the ring: skip to the start when they would wrap.
  size_t offset = unit_next_ % kUnitCapacity;
  if (offset + count > kUnitCapacity) unit_next_ += kUnitCapacity - offset;
  record.unit_begin = unit_next_;
  record.unit_count = static_cast<uint16_t>(count);
  std::copy_n(units.begin(), count,
              units_.begin() + static_cast<std::ptrdiff_t>(unit_next_ % kUnitCapacity));
  unit_next_ += count;
}

SentPacketLog::Record* SentPacketLog::Find(uint16_t sequence) {
  Record& record = records_[sequence % kCapacity];
  if (!record.valid || record.sequence != sequence) return nullptr;
  return &record;
}

std::span<const uint16_t> SentPacketLog::Units(const Record& record) const {
  if (record.unit_count == 0 || unit_next_ - record.unit_begin > kUnitCapacity) return {};
  return std::span<const uint16_t>(units_.data() + record.unit_begin % kUnitCapacity,
                                   record.unit_count);
}

bool ReceivedPacketLog::Has(uint16_t sequence) const {
  return seen_[sequence % kCapacity] == (sequence | kValid);
}

bool ReceivedPacketLog::IsDuplicate(uint16_t sequence) const {
  if (!any_) return false;
  int diff = SequenceDiff(sequence, newest_);
  if (diff > 0) return false;
  if (diff <= -static_cast<int>(kCapacity)) return true;
  return Has(sequence);
}

void ReceivedPacketLog::Record(uint16_t sequence) {
  if (!any_) {
    any_ = true;
    newest_ = sequence;
  } else if (SequenceGreater(sequence, newest_)) {
    // Forget the slots of the sequences skipped over, so they read as not received.
    int skipped = std::min<int>(SequenceDiff(sequence, newest_) - 1, kCapacity);
    for (int i = 1; i <= skipped; ++i) seen_[static_cast<uint16_t>(newest_ + i) % kCapacity] = 0;
    newest_ = sequence;
  }
  seen_[sequence % kCapacity] = sequence | kValid;
}

uint32_t ReceivedPacketLog::AckBits() const {
  if (!any_) return 0;
  uint32_t bits = 0;
  for (uint32_t i = 0; i < 32; ++i) {
    if (Has(static_cast<uint16_t>(newest_ - 1 - i))) bits |= 1u << i;
  }
  return bits;
}

}  // namespace edgephys
