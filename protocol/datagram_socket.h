// DatagramSocket: the one I/O seam of edgephys. The relay, the client SDK and the connection
// code never touch the OS directly; they are handed a DatagramSocket, so tests can put an
// in-process InMemoryNetwork (protocol/testing/) or a NetworkSimulator
// (protocol/network_simulator.h) underneath and pump everything deterministically with
// injected time.
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

  // Arrival times, opt-in (off until asked for; the relay never asks). Asks the socket to record
  // when each datagram arrives; returns true if it will. The default (simulated and in-memory
  // networks, whose "arrival" is the read) returns false. Call before the socket is shared.
  virtual bool EnableArrivalTimes() { return false; }

  // As ReceiveFrom(), and sets `*arrival_unix_s` to the time the datagram arrived at this host:
  // seconds since the Unix epoch on CLOCK_REALTIME (the kernel's software receive timestamp,
  // ~0.25 us resolution as a double), or to 0 ("unknown") when arrival times are not enabled,
  // not supported or the OS attached none. Callers that need a time anyway take the time of
  // the read (ClientConfig::record_arrival_times does, and counts it). `*arrival_unix_s` is
  // meaningful only when the result is non-zero.
  virtual size_t ReceiveFromTimed(Endpoint* from, std::span<uint8_t> buffer,
                                  double* arrival_unix_s) {
    *arrival_unix_s = 0;
    return ReceiveFrom(from, buffer);
  }

  // The address peers send to.
  virtual Endpoint LocalEndpoint() const = 0;

  // Sends whatever a batching socket queued (relay shards); returns how many datagrams the OS
  // refused (lost, as UDP may lose them). Unbuffered sockets send in SendTo() and return 0.
  virtual size_t Flush() { return 0; }
};

}  // namespace edgephys
