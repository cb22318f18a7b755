// Parsing and printing of "host:port" endpoints ("127.0.0.1:7777", "[::1]:7777", ":7777").
#pragma once

#include <string>
#include <string_view>

#include "protocol/datagram_socket.h"
#include "protocol/status.h"

namespace edgephys {

// Accepts a numeric IPv4 or bracketed IPv6 address, or no host (any IPv4 address), then a
// port. kInvalidArgument otherwise (host names are not resolved).
Result<Endpoint> ParseEndpoint(std::string_view text);
std::string FormatEndpoint(const Endpoint& endpoint);

}  // namespace edgephys
