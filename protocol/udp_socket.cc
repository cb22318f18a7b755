// Asio's scheduler trips GCC's -Wnull-dereference after inlining (a false positive inside a
// system header, reported at its use site); silence it for this file only.
#pragma GCC diagnostic ignored "-Wnull-dereference"

#include "protocol/udp_socket.h"

#include <poll.h>
#include <sys/socket.h>

#include <asio/ip/v6_only.hpp>
#include <cerrno>
#include <cmath>
#include <ctime>

namespace edgephys {
namespace {

constexpr int kSocketBufferBytes = 4 << 20;
constexpr size_t kMaxUdpPayload = 65507;

// Plain IPv4 for IPv4-mapped IPv6 endpoints, unchanged otherwise.
Endpoint Normalize(const Endpoint& endpoint) {
  if (endpoint.address().is_v6()) {
    asio::ip::address_v6 v6 = endpoint.address().to_v6();
    if (v6.is_v4_mapped()) {
      return Endpoint(asio::ip::make_address_v4(asio::ip::v4_mapped, v6), endpoint.port());
    }
  }
  return endpoint;
}

}  // namespace

UdpSocket::UdpSocket() : socket_(io_) {}

UdpSocket::~UdpSocket() {
  asio::error_code ignored;
  socket_.close(ignored);
}

Result<std::unique_ptr<UdpSocket>> UdpSocket::Open(const Endpoint& bind) {
  std::unique_ptr<UdpSocket> socket(new UdpSocket());
  asio::ip::udp::socket& s = socket->socket_;
  asio::error_code ec;
  s.open(bind.protocol(), ec);
  if (ec) return Status(StatusCode::kIoError, "cannot open UDP socket");
  if (bind.address().is_v6() && bind.address().is_unspecified()) {
    s.set_option(asio::ip::v6_only(false), ec);  // dual-stack where the OS allows it
  }
  s.set_option(asio::socket_base::receive_buffer_size(kSocketBufferBytes), ec);
  s.set_option(asio::socket_base::send_buffer_size(kSocketBufferBytes), ec);
  ec.clear();
  s.bind(bind, ec);
  if (ec) return Status(StatusCode::kIoError, "cannot bind UDP socket");
  s.non_blocking(true, ec);
  if (ec) return Status(StatusCode::kIoError, "cannot make UDP socket non-blocking");
  socket->local_ = s.local_endpoint(ec);
  if (ec) return Status(StatusCode::kIoError, "cannot read UDP socket address");
  return socket;
}

Status UdpSocket::SendTo(const Endpoint& to, std::span<const uint8_t> data) {
  if (data.size() > kMaxUdpPayload)
    return Status(StatusCode::kInvalidArgument, "datagram too large");
  Endpoint destination = to;
  if (local_.address().is_v6() && to.address().is_v4()) {
    destination =
        Endpoint(asio::ip::make_address_v6(asio::ip::v4_mapped, to.address().to_v4()), to.port());
  } else if (local_.address().is_v4() && to.address().is_v6()) {
    destination = Normalize(to);
    if (destination.address().is_v6()) {
      return Status(StatusCode::kInvalidArgument, "IPv6 destination from an IPv4 socket");
    }
  }
  asio::error_code ec;
  socket_.send_to(asio::buffer(data.data(), data.size()), destination, 0, ec);
  if (ec) return Status(StatusCode::kIoError, "UDP send failed");
  return Status::Ok();
}

size_t UdpSocket::ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) {
  // A few attempts: a pending ICMP error (e.g. port unreachable) is reported once, then the
  // next datagram can be read.
  for (int attempt = 0; attempt < 4; ++attempt) {
    Endpoint sender;
    asio::error_code ec;
    // MSG_TRUNC makes Linux return the datagram's full length even when it was truncated.
    size_t size =
        socket_.receive_from(asio::buffer(buffer.data(), buffer.size()), sender, MSG_TRUNC, ec);
    if (!ec) {
      *from = Normalize(sender);
      return size;
    }
    if (ec == asio::error::would_block || ec == asio::error::try_again) return 0;
  }
  return 0;
}

bool UdpSocket::WaitReadable(double timeout_s) {
  if (!(timeout_s > 0)) timeout_s = 0;
  pollfd fd{};
  fd.fd = socket_.native_handle();
  fd.events = POLLIN;
  double whole = std::floor(timeout_s);
  timespec timeout{};
  timeout.tv_sec = static_cast<time_t>(whole);
  timeout.tv_nsec = static_cast<long>((timeout_s - whole) * 1e9);
  int ready = ::ppoll(&fd, 1, &timeout, nullptr);
  return ready > 0 && (fd.revents & POLLIN) != 0;
}

}  // namespace edgephys
