// Asio's scheduler trips GCC's -Wnull-dereference after inlining (a false positive inside a
// system header, reported at its use site); silence it for this file only.
#pragma GCC diagnostic ignored "-Wnull-dereference"

#include "protocol/udp_socket.h"

#include <poll.h>
#include <sys/socket.h>

#include <asio/ip/v6_only.hpp>
#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstring>
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

// The (normalized) endpoint of a sockaddr the kernel filled in; unspecified if it does not fit.
Endpoint SenderOf(const sockaddr_storage& address, socklen_t length) {
  Endpoint sender;
  if (length <= sender.capacity()) {
    std::memcpy(sender.data(), &address, length);
    sender.resize(length);
  }
  return Normalize(sender);
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
  if (ec) return Status::IoError("cannot open UDP socket");
  if (bind.address().is_v6() && bind.address().is_unspecified()) {
    s.set_option(asio::ip::v6_only(false), ec);  // dual-stack where the OS allows it
  }
  s.set_option(asio::socket_base::receive_buffer_size(kSocketBufferBytes), ec);
  s.set_option(asio::socket_base::send_buffer_size(kSocketBufferBytes), ec);
  ec.clear();
  s.bind(bind, ec);
  if (ec) return Status::IoError("cannot bind UDP socket");
  s.non_blocking(true, ec);
  if (ec) return Status::IoError("cannot make UDP socket non-blocking");
  socket->local_ = s.local_endpoint(ec);
  if (ec) return Status::IoError("cannot read UDP socket address");
  return socket;
}

Status UdpSocket::Destination(const Endpoint& to, Endpoint* destination) const {
  *destination = to;
  if (local_.address().is_v6() && to.address().is_v4()) {
    *destination =
        Endpoint(asio::ip::make_address_v6(asio::ip::v4_mapped, to.address().to_v4()), to.port());
  } else if (local_.address().is_v4() && to.address().is_v6()) {
    *destination = Normalize(to);
    if (destination->address().is_v6()) {
      return Status::InvalidArgument("IPv6 destination from an IPv4 socket");
    }
  }
  return Status::Ok();
}

Status UdpSocket::SendTo(const Endpoint& to, std::span<const uint8_t> data) {
  if (data.size() > kMaxUdpPayload)
    return Status::InvalidArgument("datagram too large");
  Endpoint destination;
  if (Status st = Destination(to, &destination); !st.ok()) return st;
  asio::error_code ec;
  socket_.send_to(asio::buffer(data.data(), data.size()), destination, 0, ec);
  if (ec) return Status::IoError("UDP send failed");
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

bool UdpSocket::EnableArrivalTimes() {
  const int on = 1;
  arrival_times_ =
      ::setsockopt(socket_.native_handle(), SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof(on)) == 0;
  return arrival_times_;
}

size_t UdpSocket::ReceiveFromTimed(Endpoint* from, std::span<uint8_t> buffer,
                                   double* arrival_unix_s) {
  *arrival_unix_s = 0;
  if (!arrival_times_) return ReceiveFrom(from, buffer);
  sockaddr_storage address{};
  iovec vector{buffer.data(), buffer.size()};
  // Room for the timestamp and a few more control messages should other options add some.
  alignas(cmsghdr) std::array<uint8_t, CMSG_SPACE(sizeof(timespec)) + 128> control;
  msghdr header{};
  header.msg_name = &address;
  header.msg_iov = &vector;
  header.msg_iovlen = 1;
  header.msg_control = control.data();
  const int fd = socket_.native_handle();
  // A few attempts, as ReceiveFrom: a pending ICMP error is reported once.
  for (int attempt = 0; attempt < 4; ++attempt) {
    header.msg_namelen = sizeof(address);
    header.msg_controllen = control.size();
    header.msg_flags = 0;
    // MSG_TRUNC: the result is the datagram's full length even when it was truncated.
    const ssize_t got = ::recvmsg(fd, &header, MSG_DONTWAIT | MSG_TRUNC);
    if (got < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
      continue;  // EINTR, or e.g. ECONNREFUSED from an earlier send: reported once, try again
    }
    *from = SenderOf(address, header.msg_namelen);
    for (cmsghdr* c = CMSG_FIRSTHDR(&header); c != nullptr; c = CMSG_NXTHDR(&header, c)) {
      if (c->cmsg_level != SOL_SOCKET || c->cmsg_type != SCM_TIMESTAMPNS ||
          c->cmsg_len < CMSG_LEN(sizeof(timespec))) {
        continue;
      }
      timespec stamp{};
      std::memcpy(&stamp, CMSG_DATA(c), sizeof(stamp));
      if (stamp.tv_sec > 0) {
        *arrival_unix_s = static_cast<double>(stamp.tv_sec) + stamp.tv_nsec * 1e-9;
      }
    }
    return static_cast<size_t>(got);
  }
  return 0;
}

size_t UdpSocket::ReceiveBatch(std::span<ReceiveSlot> slots) {
  const size_t n = std::min(slots.size(), kMaxBatch);
  if (n == 0) return 0;
  std::array<mmsghdr, kMaxBatch> headers{};
  std::array<iovec, kMaxBatch> vectors{};
  std::array<sockaddr_storage, kMaxBatch> addresses{};
  for (size_t i = 0; i < n; ++i) {
    vectors[i].iov_base = slots[i].buffer.data();
    vectors[i].iov_len = slots[i].buffer.size();
    headers[i].msg_hdr.msg_name = &addresses[i];
    headers[i].msg_hdr.msg_namelen = sizeof(sockaddr_storage);
    headers[i].msg_hdr.msg_iov = &vectors[i];
    headers[i].msg_hdr.msg_iovlen = 1;
  }
  const int fd = socket_.native_handle();
  // A few attempts, as ReceiveFrom: a pending ICMP error is reported once.
  for (int attempt = 0; attempt < 4; ++attempt) {
    // MSG_TRUNC: msg_len is the datagram's full length even when it was truncated.
    int got =
        ::recvmmsg(fd, headers.data(), static_cast<unsigned>(n), MSG_DONTWAIT | MSG_TRUNC, nullptr);
    if (got < 0) {
      if (errno == EAGAIN || errno == EWOULDBLOCK) return 0;
      if (errno == EINTR) continue;
      continue;  // e.g. ECONNREFUSED from an earlier send: reported once, try again
    }
    for (int i = 0; i < got; ++i) {
      slots[i].from = SenderOf(addresses[i], headers[i].msg_hdr.msg_namelen);
      slots[i].size = headers[i].msg_len;
    }
    return static_cast<size_t>(got);
  }
  return 0;
}

UdpSocket::BatchSendResult UdpSocket::SendBatch(std::span<const Outgoing> datagrams) {
  BatchSendResult result;
  std::array<mmsghdr, kMaxBatch> headers{};
  std::array<iovec, kMaxBatch> vectors{};
  std::array<Endpoint, kMaxBatch> destinations{};
  std::array<size_t, kMaxBatch> sizes{};
  const int fd = socket_.native_handle();
  size_t next = 0;
  while (next < datagrams.size()) {
    // Fill one batch with valid datagrams; invalid ones are refused without a system call.
    size_t n = 0;
    while (n < kMaxBatch && next < datagrams.size()) {
      const Outgoing& d = datagrams[next++];
      if (d.data.size() > kMaxUdpPayload || !Destination(d.to, &destinations[n]).ok()) {
        ++result.refused;
        continue;
      }
      vectors[n].iov_base = const_cast<uint8_t*>(d.data.data());
      vectors[n].iov_len = d.data.size();
      headers[n].msg_hdr = msghdr{};
      headers[n].msg_hdr.msg_name = destinations[n].data();
      headers[n].msg_hdr.msg_namelen = static_cast<socklen_t>(destinations[n].size());
      headers[n].msg_hdr.msg_iov = &vectors[n];
      headers[n].msg_hdr.msg_iovlen = 1;
      sizes[n] = d.data.size();
      ++n;
    }
    // sendmmsg stops at the first datagram the OS refuses: count it lost and go on after it.
    size_t done = 0;
    while (done < n) {
      int sent =
          ::sendmmsg(fd, headers.data() + done, static_cast<unsigned>(n - done), MSG_DONTWAIT);
      if (sent < 0 && errno == EINTR) continue;
      if (sent <= 0) {
        ++result.refused;
        ++done;
        continue;
      }
      for (int i = 0; i < sent; ++i) result.bytes_sent += sizes[done + static_cast<size_t>(i)];
      result.sent += static_cast<size_t>(sent);
      done += static_cast<size_t>(sent);
    }
  }
  return result;
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
