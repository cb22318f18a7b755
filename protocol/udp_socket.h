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
// Thread-safety: none; one thread owns the socket (the kernel socket itself tolerates a
// sender and a receiver thread, but this class makes no such promise). Cost: one system call
// per SendTo/ReceiveFrom/WaitReadable, no allocation.
#pragma once

#include <asio/io_context.hpp>
#include <asio/ip/udp.hpp>
#include <memory>

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

  // Blocks until a datagram is pending or `timeout_s` seconds passed (0: just checks; negative
  // values count as 0). Returns true when a datagram is pending. For simple event loops.
  bool WaitReadable(double timeout_s);

  // The OS handle, for callers that multiplex several sockets (epoll, poll). Owned by this.
  int native_handle() { return socket_.native_handle(); }

 private:
  UdpSocket();

  asio::io_context io_;  // required by Asio's socket; never run
  asio::ip::udp::socket socket_;
  Endpoint local_;
};

}  // namespace edgephys
