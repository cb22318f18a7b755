#include "protocol/endpoint.h"

#include <charconv>

namespace edgephys {

Result<Endpoint> ParseEndpoint(std::string_view text) {
  const Status bad = Status::InvalidArgument("expected host:port, [v6]:port or :port");
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
  if (error) return bad;
  return Endpoint(address, static_cast<uint16_t>(port));
}

std::string FormatEndpoint(const Endpoint& endpoint) {
  if (endpoint.address().is_v6()) {
    return "[" + endpoint.address().to_string() + "]:" + std::to_string(endpoint.port());
  }
  return endpoint.address().to_string() + ":" + std::to_string(endpoint.port());
}

}  // namespace edgephys
