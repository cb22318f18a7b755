#include "protocol/endpoint.h"

#include <netdb.h>
#include <netinet/in.h>
#include <sys/socket.h>

#include <charconv>
#include <cstring>
#include <optional>
#include <string>

namespace edgephys {

Result<Endpoint> ParseEndpoint(std::string_view text) {
  const Status bad = Status::InvalidArgument("expected host:port, [v6]:port or :port",
                                              "got '" + std::string(text) + "'");
  size_t colon = text.rfind(':');
  if (colon == std::string_view::npos) return bad;
  std::string_view host = text.substr(0, colon);
  std::string_view port_text = text.substr(colon + 1);
  unsigned port = 0;
  auto [ptr, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
  if (ec != std::errc() || ptr != port_text.data() + port_text.size() || port > 65535) return bad;
  if (host.size() >= 2 && host.front() == '[' && host.back() == ']') host = host.substr(1, host.size() - 2);
  if (host.empty()) host = "0.0.0.0";
  asio::error_code error;
  auto address = asio::ip::make_address(std::string(host), error);
  if (!error) return Endpoint(address, static_cast<uint16_t>(port));
  // A host name: resolved once, here (IPv4 preferred, as the relay binds 0.0.0.0 by default).
  addrinfo hints{};
  hints.ai_family = AF_UNSPEC;
  hints.ai_socktype = SOCK_DGRAM;
  addrinfo* found = nullptr;
  const std::string name(host);
  const int rc = getaddrinfo(name.c_str(), nullptr, &hints, &found);
  if (rc != 0 || found == nullptr) {
    return Status::InvalidArgument("cannot resolve host", "'" + name + "': " + gai_strerror(rc));
  }
  std::optional<asio::ip::address> v4, v6;
  for (addrinfo* a = found; a != nullptr; a = a->ai_next) {
    if (a->ai_family == AF_INET && !v4) {
      const auto* in = reinterpret_cast<const sockaddr_in*>(a->ai_addr);
      asio::ip::address_v4::bytes_type b;
      std::memcpy(b.data(), &in->sin_addr, b.size());
      v4 = asio::ip::address_v4(b);
    } else if (a->ai_family == AF_INET6 && !v6) {
      const auto* in6 = reinterpret_cast<const sockaddr_in6*>(a->ai_addr);
      asio::ip::address_v6::bytes_type b;
      std::memcpy(b.data(), &in6->sin6_addr, b.size());
      v6 = asio::ip::address_v6(b);
    }
  }
  freeaddrinfo(found);
  if (!v4 && !v6) return Status::InvalidArgument("host has no IP address", name);
  return Endpoint(v4 ? *v4 : *v6, static_cast<uint16_t>(port));
}

std::string FormatEndpoint(const Endpoint& endpoint) {
  if (endpoint.address().is_v6()) {
    return "[" + endpoint.address().to_string() + "]:" + std::to_string(endpoint.port());
  }
  return endpoint.address().to_string() + ":" + std::to_string(endpoint.port());
}

}  // namespace edgephys
