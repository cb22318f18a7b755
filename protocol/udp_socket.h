// UdpSocket: the DatagramSocket over a real, non-blocking UDP socket (standalone Asio).
//
// Open() binds to an IPv4 or IPv6 address (port 0 picks an ephemeral port). An IPv6 socket
// bound to the unspecified address "::" is dual-stack: it also serves IPv4 peers, reported as
// plain IPv4 endpoints; sending to an IPv4 endpoint from any IPv6 socket uses the IPv4-mapped
// address. Send and receive buffers are raised to ~4 MiB where the OS allows (best effort).
//
// Failure: Open() returns kIoError when the socket cannot be opened or bound. SendTo() returns
// kIoError when the OS refuses the datagram (e.g. the send buffer is full: the datagram is
// lost, as UDP may lose it anyway), kInvalidArgument for an IPv6 destination from an IPv4
// socket or a datagram larger than 65507 bytes. ReceiveFrom() returns 0 when nothing is
// pending (a zero-length datagram also reads as 0) and reports the full size of a datagram
// larger than the buffer (its tail is lost).
//
// Batches (Linux): ReceiveBatch() reads up to kMaxBatch datagrams with one recvmmsg(2);
// SendBatch() sends a span of datagrams with sendmmsg(2), kMaxBatch per system call. They use
// only the OS handle (no member state besides it), so SendBatch() may be called from several
// threads at once and concurrently with one thread calling ReceiveBatch() (the kernel
// serialises datagram sends and receives on one UDP socket). The single calls keep the
// one-owner rule.
//
// Arrival times (opt-in, off by default; the relay leaves them off): EnableArrivalTimes() turns
// on SO_TIMESTAMPNS, and ReceiveFromTimed() then reads with recvmsg(2) and returns the kernel's
// software receive timestamp (CLOCK_REALTIME, taken when the datagram entered the host's
// receive path, before it waits in the socket's queue). Until enabled, ReceiveFromTimed() is
// ReceiveFrom() with an unknown (0) arrival time; ReceiveFrom() and the batch calls never
// report arrival times and behave the same either way (control data is discarded). Cost: one
// recvmsg(2) and a scan of its control messages per datagram instead of one recvfrom(2), no
// allocation; while any socket on the host has timestamps on, the kernel stamps every received
// packet (one clock read each, for every socket). The first socket on a host to ask turns
// stamping on through deferred kernel work: for a moment after that, the kernel stamps a
// datagram when it is read instead.
//
// Thread-safety: none for SendTo/ReceiveFrom/ReceiveFromTimed/WaitReadable/EnableArrivalTimes;
// one thread owns the socket. See above for the batch calls. Cost: one system call per
// SendTo/ReceiveFrom/WaitReadable and per kMaxBatch datagrams of a batch call, no allocation.
#pragma once

#include <asio/io_context.hpp>
#include <asio/ip/udp.hpp>
#include <cstddef>
#include <memory>
#include <span>

#include "protocol/datagram_socket.h"
#include "protocol/status.h"

namespace edgephys {

class UdpSocket final : public DatagramSocket {
 public:
  static Result<std::unique_ptr<UdpSocket>> Open(const Endpoint& bind);

  ~UdpSocket() override;
  UdpSocket(const UdpSocket&) = delete;
  UdpSocket& operator=(const UdpSocket&) = delete;

  Status SendTo(const Endpoint& to, std::span<const uint8_t> data) override;
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override;
  Endpoint LocalEndpoint() const override { return local_; }
  // SO_TIMESTAMPNS on; false if the OS refuses (arrival times then stay unknown).
  bool EnableArrivalTimes() override;
  size_t ReceiveFromTimed(Endpoint* from, std::span<uint8_t> buffer,
                          double* arrival_unix_s) override;

  // Datagrams per recvmmsg/sendmmsg system call.
  static constexpr size_t kMaxBatch = 64;

  // One slot of ReceiveBatch(): the caller points `buffer` at its storage; ReceiveBatch sets
  // `from` and `size` (the datagram's full size, larger than buffer.size() when truncated).
  struct ReceiveSlot {
    std::span<uint8_t> buffer;
    Endpoint from;
    size_t size = 0;
  };
  // Receives up to min(slots.size(), kMaxBatch) pending datagrams with one recvmmsg(2), in
  // arrival order, into slots[0..n). Returns n (0 when nothing is pending). Never blocks.
  size_t ReceiveBatch(std::span<ReceiveSlot> slots);

  struct Outgoing {
    Endpoint to;
    std::span<const uint8_t> data;
  };
  struct BatchSendResult {
    size_t sent = 0;        // datagrams the OS accepted
    size_t bytes_sent = 0;  // their payload bytes
    size_t refused = 0;     // datagrams lost: invalid (as SendTo) or refused by the OS
  };
  // Sends every datagram of `datagrams` (sendmmsg(2), kMaxBatch per call). A datagram the OS
  // refuses (e.g. a full send buffer) is counted in `refused` and skipped; the rest are still
  // sent. sent + refused == datagrams.size(). Never blocks.
  BatchSendResult SendBatch(std::span<const Outgoing> datagrams);

  // Blocks until a datagram is pending or `timeout_s` seconds passed (0: just checks; negative
  // values count as 0). Returns true when a datagram is pending. For simple event loops.
  bool WaitReadable(double timeout_s);

  // The OS handle, for callers that multiplex several sockets (epoll, poll). Owned by this.
  int native_handle() { return socket_.native_handle(); }

 private:
  UdpSocket();
  // The address to hand the OS for `to` (IPv4-mapped from an IPv6 socket); kInvalidArgument
  // for an IPv6 destination from an IPv4 socket.
  Status Destination(const Endpoint& to, Endpoint* destination) const;

  asio::io_context io_;  // required by Asio's socket; never run
  asio::ip::udp::socket socket_;
  Endpoint local_;
  bool arrival_times_ = false;  // SO_TIMESTAMPNS on
};

}  // namespace edgephys
