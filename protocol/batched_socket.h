// BatchedSocket: a DatagramSocket over a UdpSocket that moves datagrams in batches: receives
// read up to UdpSocket::kMaxBatch pending datagrams with one recvmmsg(2) and hand them out one
// by one; sends are queued and leave with sendmmsg(2) on Flush() (or when the queue is full).
// For a single-threaded server loop that calls Flush() once per iteration (the relay does at
// the end of Relay::Update): one system call per batch instead of one per datagram.
//
// Semantics against UdpSocket: SendTo() accepts a datagram into the queue (kInvalidArgument as
// UdpSocket for one it could never send); a datagram the OS refuses at Flush() is lost, as UDP
// may lose it anyway, and counted in the value Flush() returns. Queued datagrams leave in
// order. ReceiveFrom() reports a datagram larger than kSlotBytes with its full size, as
// UdpSocket does for one larger than the caller's buffer.
//
// Ownership: `socket` is not owned and must outlive this. Thread-safety: one owning thread.
// Memory: kMaxBatch receive slots and kQueueDatagrams send slots of kSlotBytes each (~400 KiB),
// allocated once; no allocation per datagram.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "protocol/udp_socket.h"

namespace edgephys {

class BatchedSocket final : public DatagramSocket {
 public:
  static constexpr size_t kSlotBytes = 2048;      // larger datagrams are truncated on receive
  static constexpr size_t kQueueDatagrams = 256;  // queued sends before an automatic flush

  // With `batch_sends` false, SendTo() sends at once (one sendto(2) each, as UdpSocket) and
  // only receives are batched.
  explicit BatchedSocket(UdpSocket* socket, bool batch_sends = true);

  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override;
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override;
  Endpoint LocalEndpoint() const override { return socket_->LocalEndpoint(); }
  // Sends every queued datagram; returns how many the OS refused (lost).
  size_t Flush() override;

  // Totals since construction, for tests and diagnostics.
  uint64_t send_calls() const { return send_calls_; }
  uint64_t receive_calls() const { return receive_calls_; }

 private:
  UdpSocket* socket_;
  bool batch_sends_;
  std::vector<uint8_t> receive_storage_;
  std::array<UdpSocket::ReceiveSlot, UdpSocket::kMaxBatch> received_;
  size_t received_count_ = 0;
  size_t received_next_ = 0;
  std::vector<uint8_t> send_storage_;
  std::vector<UdpSocket::Outgoing> queued_;
  uint64_t send_calls_ = 0;
  uint64_t receive_calls_ = 0;
};

}  // namespace edgephys
