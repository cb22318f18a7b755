// HttpGate: an HTTP/1.1 front that no client can starve, for the relay's admin API and its
// /metrics endpoint. cpp-httplib (Debian's libcpp-httplib-dev) parses and routes each request;
// the gate owns the sockets.
//
// One gate thread accepts and reads every connection without blocking (epoll). A request is
// handed to the worker threads only once it has fully arrived, so a slow client holds a
// connection slot, never a worker. What the gate enforces, in order:
//   - connections: at most max_connections open, at most max_per_address from one address.
//     A new connection over either cap closes the oldest connection still sending its request
//     (of that address, or of all); if none is, the new one gets 503 and is closed.
//   - a whole-request deadline: the request line, headers and body must all arrive within
//     request_deadline of the accept (not per read); else 408 and close.
//   - the head: at most max_head_bytes (431), at most max_headers header lines (431), no
//     control byte but HTAB in it (400), no whitespace around an Authorization value (400),
//     no Transfer-Encoding (411: send Content-Length), Content-Length at most max_body_bytes
//     (413). A request without Content-Length has an empty body.
//   - at most max_queued complete requests waiting for a worker (503 beyond).
//   - a response deadline: the response must be taken by the client within response_deadline.
// `GET <health_path>` (and HEAD) is answered on the gate thread itself from `health`, which
// must not block: liveness never waits behind the workers.
// Every connection carries one request ("Connection: close").
//
// Thread-safety: routes() is configured before Start(); Start() and Stop() from one thread;
// handlers run on the worker threads, several at once. stats() from any thread.
#pragma once

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include "protocol/status.h"

namespace httplib {
class Server;
}

namespace edgephys::http {

struct HealthAnswer {
  int status = 200;
  std::string json;  // the body (application/json)
};

struct GateOptions {
  std::string address = "127.0.0.1:0";  // numeric host:port ("[::1]:9465"); port 0: any
  size_t workers = 4;
  std::chrono::milliseconds request_deadline{2000};   // accept -> last request byte
  std::chrono::milliseconds response_deadline{5000};  // response ready -> last byte taken
  size_t max_connections = 256;
  size_t max_per_address = 16;
  size_t max_queued = 64;
  size_t max_head_bytes = 16 * 1024;
  size_t max_headers = 100;
  size_t max_body_bytes = 64 * 1024;
  std::string health_path;               // empty: no path answered on the gate thread
  std::function<HealthAnswer()> health;  // non-blocking, thread-safe
};

// What the gate refused or cut off, since Start (relaxed counters).
struct GateStats {
  uint64_t accepted = 0;
  uint64_t served = 0;          // requests handed to the workers or answered by health
  uint64_t health_answers = 0;  // answered on the gate thread
  uint64_t evicted = 0;         // closed to make room for a newer connection
  uint64_t refused = 0;         // 503 at accept: every slot busy with a request in work
  uint64_t timed_out = 0;       // request or response deadline passed
  uint64_t bad_requests = 0;    // 400/411/413/431 from the gate's own checks
  uint64_t queue_full = 0;      // 503: too many complete requests waiting
};

class HttpGate {
 public:
  explicit HttpGate(GateOptions options);
  ~HttpGate();  // Stop()
  HttpGate(const HttpGate&) = delete;
  HttpGate& operator=(const HttpGate&) = delete;

  // The router: register handlers, error and exception handlers here before Start().
  httplib::Server& routes();

  // Binds and starts the gate and worker threads. kInvalidArgument: an unparsable address;
  // kIoError: it cannot be bound (the reason included).
  Status Start();
  // Closes every connection, finishes the handlers running, joins the threads. Idempotent.
  void Stop();

  // "host:port" actually bound; valid after Start().
  const std::string& address() const { return address_; }
  uint16_t port() const { return port_; }
  GateStats stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  std::string address_;
  uint16_t port_ = 0;
};

}  // namespace edgephys::http
