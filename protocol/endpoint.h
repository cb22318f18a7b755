// Parsing and printing of "host:port" endpoints ("127.0.0.1:7777", "[::1]:7777", ":7777").
#pragma once

#include <string>
#include <string_view>

#include "protocol/datagram_socket.h"
#include "protocol/status.h"

namespace edgephys {

// Accepts host:port where host is a numeric IPv4 address, a bracketed IPv6 address, a host
// name (resolved here with getaddrinfo, blocking; an IPv4 address is preferred) or nothing (any
// IPv4 address). kInvalidArgument, naming the text or the resolver's error, otherwise.
Result<Endpoint> ParseEndpoint(std::string_view text);
std::string FormatEndpoint(const Endpoint& endpoint);

}  // namespace edgephys
