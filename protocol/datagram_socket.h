// DatagramSocket: the one I/O seam of edgephys. The relay, the client SDK and the connection
// code never touch the OS directly; they are handed a DatagramSocket, so tests can put a
// NetworkSimulator (network_simulator.h) or an in-process InMemoryNetwork underneath and pump
// everything deterministically with injected time.
#pragma once

#include <asio/ip/udp.hpp>
#include <cstddef>
#include <cstdint>
#include <span>

#include "protocol/status.h"

namespace edgephys {

using Endpoint = asio::ip::udp::endpoint;

class DatagramSocket {
 public:
  virtual ~DatagramSocket() = default;

  // Sends one datagram to `to`. Never blocks. A kIoError means the datagram is lost (as UDP
  // may lose it anyway); callers count it and carry on.
  virtual Status SendTo(const Endpoint& to, std::span<const uint8_t> data) = 0;

  // Copies one pending datagram into `buffer` and sets `*from`. Returns its size, or 0 when
  // nothing is pending. A datagram larger than `buffer` is truncated to buffer.size() and
  // reported with its full size so the caller can drop it as too large. Never blocks.
  virtual size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) = 0;

  // The address peers send to.
  virtual Endpoint LocalEndpoint() const = 0;
};

}  // namespace edgephys
