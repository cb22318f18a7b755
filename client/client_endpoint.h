// Between the client SDK's RelayAddress (client/client.h, no Asio) and the Asio Endpoint that
// DatagramSocket speaks (protocol/datagram_socket.h), for code in this tree that holds
// Endpoints: tests, loadgen, the PhyS worker, the C API.
//
// Thread-safety: pure functions over values.
#pragma once

#include "client/client.h"
#include "protocol/datagram_socket.h"
#include "protocol/status.h"

namespace edgephys {

// The address and port of `endpoint`, host in canonical text ("127.0.0.1", "::1").
RelayAddress ToRelayAddress(const Endpoint& endpoint);
// kInvalidArgument if `address.host` is not a numeric IPv4 or IPv6 address (no name lookup).
Result<Endpoint> ToEndpoint(const RelayAddress& address);

}  // namespace edgephys
