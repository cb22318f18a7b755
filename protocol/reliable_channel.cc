#include "protocol/reliable_channel.h"

#include <algorithm>
#include <limits>

#include "protocol/sequence.h"

namespace edgephys {

// ---------------------------------------------------------------------------------------------
// ReliableSender

ReliableSender::ReliableSender(size_t max_message_size, size_t max_pending_bytes)
    : max_message_size_(max_message_size), max_pending_bytes_(max_pending_bytes) {}

Status ReliableSender::Queue(std::span<const uint8_t> message) {
  if (message.empty()) return Status::InvalidArgument("empty reliable message");
  if (message.size() > max_message_size_) {
    return Status::TooLarge("reliable message exceeds max_message_size");
  }
  if (pending_bytes_ + message.size() > max_pending_bytes_) {
    return Status::QueueFull("reliable queue full");
  }
  Compact();
  uint64_t offset = bytes_base_ + bytes_.size();
  bytes_.insert(bytes_.end(), message.begin(), message.end());
  size_t remaining = message.size();
  while (remaining > 0) {
    Unit unit;
    unit.offset = offset;
    unit.size = static_cast<uint16_t>(std::min(remaining, kMaxReliableUnitSize));
    remaining -= unit.size;
    offset += unit.size;
    unit.last = remaining == 0;
    units_.PushBack(unit);
    ++unsent_units_;
  }
  pending_bytes_ += message.size();
  return Status::Ok();
}

size_t ReliableSender::sendable_count() const {
  return std::min<size_t>(units_.size(), kReliableWindow);
}

bool ReliableSender::IsDue(size_t index, double now, double resend_timeout_s) const {
  const Unit& unit = units_[index];
  if (unit.acked) return false;
  return !unit.sent || now - unit.last_sent >= resend_timeout_s;
}

double ReliableSender::OldestInFlight(size_t scan) const {
  double oldest = std::numeric_limits<double>::infinity();
  const size_t n = std::min(sendable_count(), scan);
  for (size_t i = 0; i < n; ++i) {
    const Unit& unit = units_[i];
    if (unit.sent && !unit.acked) oldest = std::min(oldest, unit.last_sent);
  }
  return oldest;
}

ReliableUnitView ReliableSender::View(size_t index) const {
  const Unit& unit = units_[index];
  ReliableUnitView view;
  view.id = static_cast<uint16_t>(base_id_ + index);
  view.last = unit.last;
  view.data = std::span<const uint8_t>(bytes_.data() + (unit.offset - bytes_base_), unit.size);
  return view;
}

bool ReliableSender::MarkSent(size_t index, double now) {
  Unit& unit = units_[index];
  bool resend = unit.sent;
  if (!resend) --unsent_units_;
  unit.sent = true;
  unit.last_sent = now;
  return resend;
}

void ReliableSender::Ack(uint16_t unit_id) {
  size_t index = static_cast<uint16_t>(unit_id - base_id_);
  if (index >= sendable_count()) return;  // already acknowledged and retired, or never sent
  Unit& unit = units_[index];
  if (unit.acked || !unit.sent) return;
  unit.acked = true;
  pending_bytes_ -= unit.size;
  while (!units_.empty() && units_.front().acked) {
    bytes_head_ = units_.front().offset + units_.front().size;
    units_.PopFront();
    ++base_id_;
  }
}

void ReliableSender::Compact() {
  // Drop retired bytes from the front once they are at least half the buffer, so the buffer
  // stays within twice the pending bytes and the move is amortised O(1) per byte.
  size_t dead = static_cast<size_t>(bytes_head_ - bytes_base_);
  if (dead == 0 || dead < bytes_.size() / 2) return;
  bytes_.erase(bytes_.begin(), bytes_.begin() + static_cast<std::ptrdiff_t>(dead));
  bytes_base_ = bytes_head_;
}

// ---------------------------------------------------------------------------------------------
// ReliableReceiver

ReliableReceiver::ReliableReceiver(size_t max_message_size, size_t max_held_bytes)
    : max_message_size_(max_message_size), max_held_bytes_(max_held_bytes) {}

ReliableReceiver::Placement ReliableReceiver::Classify(uint16_t id) const {
  int diff = SequenceDiff(id, next_id_);
  if (diff < 0) return Placement::kDuplicate;
  if (diff >= kReliableWindow) return Placement::kOutsideWindow;
  if (diff > 0 && !slots_.empty() && slots_[id % kReliableWindow].present) {
    return Placement::kDuplicate;
  }
  return Placement::kInWindow;
}

size_t ReliableReceiver::held_bytes() const {
  const size_t table = slots_.capacity() * sizeof(Slot) + spare_.capacity() * sizeof(spare_[0]);
  return partial_bytes() + (message_.empty() ? message_.capacity() : 0) +
         spare_.size() * kMaxReliableUnitSize + table;
}

size_t ReliableReceiver::partial_bytes() const {
  return (message_.empty() ? 0 : message_.capacity()) + in_use_capacity_;
}

bool ReliableReceiver::Admits(std::span<const ReliableUnitView> units) const {
  // Units past the next expected one are counted as if the whole span up to the furthest
  // buffered one were full units: the gap before them is later filled in order, without
  // another check, and must fit too.
  size_t span = buffered_bytes_ > 0 ? static_cast<size_t>(SequenceDiff(buffered_end_, next_id_)) : 0;
  bool out_of_order = false;
  for (const ReliableUnitView& unit : units) {
    if (Classify(unit.id) != Placement::kInWindow) continue;
    if (unit.id == next_id_) return true;  // progress is always possible
    out_of_order = true;
    span = std::max(span, static_cast<size_t>(SequenceDiff(unit.id, next_id_)) + 1);
  }
  if (!out_of_order) return true;
  const size_t table = kReliableWindow * sizeof(Slot) + kMaxSpareBuffers * sizeof(spare_[0]);
  return message_.capacity() + table + span * kMaxReliableUnitSize <= max_held_bytes_;
}

Status ReliableReceiver::Receive(const ReliableUnitView& unit, ConnectionHandler& handler,
                                 uint64_t* delivered, uint64_t* duplicates) {
  switch (Classify(unit.id)) {
    case Placement::kDuplicate:
      ++*duplicates;
      return Status::Ok();
    case Placement::kOutsideWindow:
      return Status::ResourceExhausted("reliable unit outside the window");
    case Placement::kInWindow:
      break;
  }
  if (unit.id != next_id_) {
    if (slots_.empty()) {
      slots_.resize(kReliableWindow);
      spare_.reserve(kMaxSpareBuffers);
    }
    Slot& slot = slots_[unit.id % kReliableWindow];  // not present: holds no buffer
    slot.present = true;
    slot.last = unit.last;
    if (!spare_.empty()) {
      slot.data = std::move(spare_.back());
      spare_.pop_back();
    } else {
      slot.data.reserve(kMaxReliableUnitSize);  // every buffer is one unit: reusable for any
    }
    slot.data.assign(unit.data.begin(), unit.data.end());
    in_use_capacity_ += slot.data.capacity();
    if (buffered_bytes_ == 0 || SequenceDiff(unit.id, buffered_end_) >= 0) {
      buffered_end_ = static_cast<uint16_t>(unit.id + 1);
    }
    buffered_bytes_ += unit.data.size();
    return Status::Ok();
  }
  Status status = Append(unit.data, unit.last, handler, delivered);
  while (status.ok() && !slots_.empty() && slots_[next_id_ % kReliableWindow].present) {
    Slot& slot = slots_[next_id_ % kReliableWindow];
    slot.present = false;
    buffered_bytes_ -= slot.data.size();
    status = Append(slot.data, slot.last, handler, delivered);
    // Its bytes moved into message_: the buffer is kept for reuse (up to kMaxSpareBuffers,
    // no allocation: spare_ is reserved) or freed.
    in_use_capacity_ -= slot.data.capacity();
    if (spare_.size() < kMaxSpareBuffers) {
      spare_.push_back(std::move(slot.data));
    }
    std::vector<uint8_t>().swap(slot.data);
  }
  return status;
}

Status ReliableReceiver::Append(std::span<const uint8_t> data, bool last,
                                ConnectionHandler& handler, uint64_t* delivered) {
  const size_t size = message_.size() + data.size();
  if (size > max_message_size_) {
    return Status::TooLarge("reliable message exceeds max_message_size");
  }
  if (size > message_.capacity()) {
    // Doubles up to kMessageGrowthStep, then grows by that much at a time, never past
    // max_message_size: at most kMessageGrowthStep allocated beyond the bytes held.
    const size_t step = std::min(message_.capacity(), kMessageGrowthStep);
    message_.reserve(std::min(max_message_size_, std::max(size, message_.capacity() + step)));
  }
  message_.insert(message_.end(), data.begin(), data.end());
  ++next_id_;
  if (last) {
    ++*delivered;
    handler.OnReliableMessage(message_);
    message_.clear();
    if (message_.capacity() > kRetainedMessageBytes) std::vector<uint8_t>().swap(message_);
  }
  return Status::Ok();
}

}  // namespace edgephys
