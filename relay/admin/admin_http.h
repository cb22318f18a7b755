// AdminHttpServer: the admin API's HTTP front on its own port (cpp-httplib, Debian's
// libcpp-httplib-dev), serving the route table of relay/admin/admin_routes.h.
//
// What every request goes through, in order: the route (404 not_found, JSON), the body limit
// (413 body_too_large), the bearer key when the route needs one and a key is configured (401
// unauthorized; compared in constant time over SHA-256 digests), JSON parsing (400 bad_json;
// an empty body is {}), then the handler. Responses are JSON with Cache-Control: no-store.
//
// Security: with no key the server refuses any address that is not loopback (Start fails).
// The key travels in "Authorization: Bearer <key>"; serve the port through TLS termination
// if it leaves the host.
//
// Sockets: metrics/http_gate.h owns them. A request reaches a worker only once it has fully
// arrived within `request_deadline` of the accept; connections are capped per address and in
// total (a newcomer closes the oldest slow sender); more than 100 header lines get 431, a
// control byte or whitespace after the Authorization value 400. GET /healthz is answered on
// the gate thread from AdminBackend::Health() (which must not block), so liveness never waits
// behind the workers. A method a path does not take gets 405 with Allow.
//
// Thread-safety: Start() and Stop() from one thread; requests are served on `threads` worker
// threads, which call the AdminBackend concurrently. A connection carries one request.
#pragma once

#include <chrono>
#include <memory>
#include <string>

#include "protocol/status.h"
#include "relay/admin/admin_api.h"

namespace edgephys::http {
class HttpGate;
}

namespace edgephys::admin {

struct AdminHttpOptions {
  std::string address = "127.0.0.1:9465";  // numeric host:port; port 0 picks a free one
  std::string key;                          // bearer key; empty: no key (loopback only)
  size_t max_body_bytes = 64 * 1024;
  size_t threads = 4;        // requests served at once (one connection per request)
  std::chrono::milliseconds request_deadline{2000};  // accept -> last request byte
  size_t max_connections = 256;  // open at once, all addresses
  size_t max_per_address = 16;   // open at once from one address
};

class AdminHttpServer {
 public:
  // Binds and starts serving. kInvalidArgument: an unparsable address, or a non-loopback one
  // without a key. kIoError: the address cannot be bound. `backend` must outlive the server.
  static Result<std::unique_ptr<AdminHttpServer>> Start(const AdminHttpOptions& options,
                                                        AdminBackend* backend);
  ~AdminHttpServer();  // Stop()
  AdminHttpServer(const AdminHttpServer&) = delete;
  AdminHttpServer& operator=(const AdminHttpServer&) = delete;

  // Stops accepting, closes the connections, finishes the handlers running. Idempotent.
  void Stop();
  // "host:port" actually bound (the chosen port when 0 was asked).
  const std::string& address() const { return address_; }

 private:
  AdminHttpServer() = default;
  std::unique_ptr<http::HttpGate> gate_;
  std::string address_;
};

// True if `presented` equals `expected`, in time independent of where they differ.
bool KeyMatches(const std::string& presented, const std::string& expected);

}  // namespace edgephys::admin
