// InMemoryNetwork: an in-process stand-in for UDP. Sockets created from one network deliver
// into each other's receive queues at once, so a test can pump a relay and many clients in one
// thread, deterministically, without touching the OS. Put a NetworkSimulator on top of a socket
// to add loss, latency and reordering. Test support: edgephys::protocol_testing.
//
// Addressing: a datagram goes to the socket bound to exactly its destination endpoint, or,
// failing that, to a socket bound to the unspecified address (0.0.0.0 or ::) of the same
// family and port. A datagram to an unknown destination vanishes (counted). The sender is
// reported as the sending socket's bound endpoint.
//
// Lifetime: the network and its sockets share their state, so they may be destroyed in any
// order; a socket outliving its network still works (it can reach the other sockets still
// alive). Destroying a socket unbinds its address and discards its queue.
// Memory: each socket queues at most `max_queued_per_socket` datagrams (more are dropped and
// counted, like a full kernel buffer). Datagram buffers are reused once a queue has reached
// its steady-state size.
// Thread-safety: all sockets and the network may be used from different threads (one mutex
// per network). Cost: one copy per datagram.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>

#include "protocol/datagram_socket.h"

namespace edgephys {

struct InMemoryNetworkStats {
  uint64_t delivered = 0;       // datagrams put in a receive queue
  uint64_t no_destination = 0;  // datagrams to an endpoint nobody is bound to
  uint64_t queue_full = 0;      // datagrams dropped because the destination queue was full
};

class InMemoryNetwork {
 public:
  static constexpr size_t kDefaultMaxQueuedPerSocket = 65536;

  explicit InMemoryNetwork(size_t max_queued_per_socket = kDefaultMaxQueuedPerSocket);
  ~InMemoryNetwork();
  InMemoryNetwork(const InMemoryNetwork&) = delete;
  InMemoryNetwork& operator=(const InMemoryNetwork&) = delete;

  // A socket bound to `address`. Port 0 picks a free port (from 49152 up). Returns nullptr if
  // another live socket of this network is already bound to the same endpoint.
  std::unique_ptr<DatagramSocket> CreateSocket(const Endpoint& address);

  InMemoryNetworkStats stats() const;

  struct State;  // shared by the network and its sockets (in_memory_network.cc)

 private:
  std::shared_ptr<State> state_;
};

}  // namespace edgephys
