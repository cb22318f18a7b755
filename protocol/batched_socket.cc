#include "protocol/batched_socket.h"

#include <algorithm>
#include <cstring>

namespace edgephys {

BatchedSocket::BatchedSocket(UdpSocket* socket, bool batch_sends)
    : socket_(socket),
      batch_sends_(batch_sends),
      receive_storage_(UdpSocket::kMaxBatch * kSlotBytes),
      send_storage_(batch_sends ? kQueueDatagrams * kSlotBytes : 0) {
  if (batch_sends_) queued_.reserve(kQueueDatagrams);
}

Status BatchedSocket::SendTo(const Endpoint& to, std::span<const uint8_t> data) {
  if (!batch_sends_) {
    ++send_calls_;
    return socket_->SendTo(to, data);
  }
  if (data.size() > kSlotBytes) {
    // Rare (the protocol's datagrams are at most kMaxPacketSize): send it alone, in order.
    (void)Flush();
    ++send_calls_;
    return socket_->SendTo(to, data);
  }
  if (queued_.size() == kQueueDatagrams) (void)Flush();
  uint8_t* slot = send_storage_.data() + queued_.size() * kSlotBytes;
  std::memcpy(slot, data.data(), data.size());
  queued_.push_back({to, std::span<const uint8_t>(slot, data.size())});
  return Status::Ok();
}

size_t BatchedSocket::Flush() {
  if (queued_.empty()) return 0;
  send_calls_ += (queued_.size() + UdpSocket::kMaxBatch - 1) / UdpSocket::kMaxBatch;
  UdpSocket::BatchSendResult result = socket_->SendBatch(queued_);
  queued_.clear();
  return result.refused;
}

size_t BatchedSocket::ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) {
  if (received_next_ == received_count_) {
    for (size_t i = 0; i < received_.size(); ++i) {
      received_[i].buffer = std::span<uint8_t>(receive_storage_.data() + i * kSlotBytes, kSlotBytes);
    }
    ++receive_calls_;
    received_count_ = socket_->ReceiveBatch(received_);
    received_next_ = 0;
    if (received_count_ == 0) return 0;
  }
  const UdpSocket::ReceiveSlot& slot = received_[received_next_++];
  *from = slot.from;
  const size_t stored = std::min(slot.size, kSlotBytes);
  std::memcpy(buffer.data(), slot.buffer.data(), std::min(stored, buffer.size()));
  // The full size, as UdpSocket reports a truncated datagram (the caller drops it as too large).
  return slot.size;
}

}  // namespace edgephys
