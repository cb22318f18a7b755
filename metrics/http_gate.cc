#include "metrics/http_gate.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <httplib.h>
#include <netinet/in.h>
#include <sys/epoll.h>
#include <sys/eventfd.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <deque>
#include <map>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <vector>

#include "metrics/http_head.h"
#include "protocol/endpoint.h"

namespace edgephys::http {
namespace {

using Clock = std::chrono::steady_clock;

// Exposes httplib's request processing over any Stream (the gate's buffered request).
class Router : public httplib::Server {
 public:
  using httplib::Server::process_request;
};

// The complete request as read by the gate, and the response the router writes.
class BufferedExchange final : public httplib::Stream {
 public:
  BufferedExchange(const std::string& request, std::string peer_ip, int peer_port,
                   std::string local_ip, int local_port)
      : in_(request), peer_ip_(std::move(peer_ip)), local_ip_(std::move(local_ip)),
        peer_port_(peer_port), local_port_(local_port) {}
  bool is_readable() const override { return true; }
  bool is_writable() const override { return true; }
  ssize_t read(char* ptr, size_t size) override {
    size_t n = std::min(size, in_.size() - pos_);
    std::memcpy(ptr, in_.data() + pos_, n);
    pos_ += n;
    return static_cast<ssize_t>(n);
  }
  ssize_t write(const char* ptr, size_t size) override {
    out_.append(ptr, size);
    return static_cast<ssize_t>(size);
  }
  void get_remote_ip_and_port(std::string& ip, int& port) const override {
    ip = peer_ip_;
    port = peer_port_;
  }
  void get_local_ip_and_port(std::string& ip, int& port) const override {
    ip = local_ip_;
    port = local_port_;
  }
  socket_t socket() const override { return INVALID_SOCKET; }
  std::string& out() { return out_; }

 private:
  const std::string& in_;
  size_t pos_ = 0;
  std::string out_;
  std::string peer_ip_, local_ip_;
  int peer_port_, local_port_;
};

const char* Reason(int status) {
  switch (status) {
    case 200: return "OK";
    case 400: return "Bad Request";
    case 408: return "Request Timeout";
    case 411: return "Length Required";
    case 413: return "Payload Too Large";
    case 431: return "Request Header Fields Too Large";
    case 503: return "Service Unavailable";
    default: return "Error";
  }
}

// A complete response with a JSON body, closing the connection.
std::string JsonResponse(int status, const std::string& body, bool head_only = false) {
  std::string r = "HTTP/1.1 " + std::to_string(status) + " " + Reason(status) +
                  "\r\nContent-Type: application/json\r\nCache-Control: no-store\r\n"
                  "Content-Length: " + std::to_string(body.size()) + "\r\nConnection: close\r\n\r\n";
  if (!head_only) r += body;
  return r;
}

std::string ErrorResponse(int status, const char* code, const std::string& message) {
  std::string body = std::string("{\"error\":{\"code\":\"") + code + "\",\"message\":\"" + message +
                     "\"}}";
  return JsonResponse(status, body);
}

std::string IpOf(const sockaddr_storage& ss, int* port) {
  char buf[INET6_ADDRSTRLEN] = {};
  if (ss.ss_family == AF_INET6) {
    const auto& a = reinterpret_cast<const sockaddr_in6&>(ss);
    inet_ntop(AF_INET6, &a.sin6_addr, buf, sizeof(buf));
    *port = ntohs(a.sin6_port);
  } else {
    const auto& a = reinterpret_cast<const sockaddr_in&>(ss);
    inet_ntop(AF_INET, &a.sin_addr, buf, sizeof(buf));
    *port = ntohs(a.sin_port);
  }
  return buf;
}

}  // namespace

struct HttpGate::Impl {
  enum class State { kReading, kWorking, kWriting, kLingering };
  struct Conn {
    int fd = -1;
    uint64_t id = 0;
    std::string ip;
    int port = 0;
    Clock::time_point accepted;
    Clock::time_point deadline;
    State state = State::kReading;
    std::string in;
    size_t request_bytes = 0;  // head + body, once the head is parsed; 0 before
    bool sent_continue = false;
    std::string out;
    size_t out_pos = 0;
  };
  struct Job {
    uint64_t id;
    std::string request;
    std::string ip;
    int port;
  };

  explicit Impl(GateOptions o) : options(std::move(o)) {}

  GateOptions options;
  Router router;
  int listen_fd = -1, epoll_fd = -1, wake_fd = -1;
  std::string local_ip;
  int local_port = 0;
  std::thread gate_thread;
  std::vector<std::thread> workers;
  std::atomic<bool> stopping{false};

  // Gate-thread state.
  std::unordered_map<uint64_t, Conn> conns;
  std::map<std::string, size_t> per_address;
  uint64_t next_id = 1;
  Clock::time_point accept_paused_until{};

  // Worker queue and results.
  std::mutex mu;
  std::condition_variable cv;
  std::deque<Job> jobs;
  std::vector<std::pair<uint64_t, std::string>> done;

  struct {
    std::atomic<uint64_t> accepted{0}, served{0}, health{0}, evicted{0}, refused{0},
        timed_out{0}, bad{0}, queue_full{0};
  } stats;

  void Close(uint64_t id) {
    auto it = conns.find(id);
    if (it == conns.end()) return;
    Conn& c = it->second;
    epoll_ctl(epoll_fd, EPOLL_CTL_DEL, c.fd, nullptr);
    ::close(c.fd);
    if (auto p = per_address.find(c.ip); p != per_address.end() && --p->second == 0) {
      per_address.erase(p);
    }
    conns.erase(it);
  }

  // The oldest connection still sending its request, of `ip` (or of all when empty).
  uint64_t OldestReading(const std::string* ip) const {
    uint64_t best = 0;
    Clock::time_point best_t = Clock::time_point::max();
    for (const auto& [id, c] : conns) {
      if (c.state != State::kReading || (ip != nullptr && c.ip != *ip)) continue;
      if (c.accepted < best_t) best = id, best_t = c.accepted;
    }
    return best;
  }

  // The connection to close for a newcomer: the oldest one still sending its request, once
  // what already waits in its socket is read (a request that arrived while the gate was
  // accepting is served, not evicted). 0: every connection has its request in work.
  uint64_t EvictionVictim(const std::string* ip) {
    for (;;) {
      const uint64_t victim = OldestReading(ip);
      if (victim == 0) return 0;
      OnReadable(victim);
      auto it = conns.find(victim);
      if (it != conns.end() && it->second.state == State::kReading) return victim;
    }
  }

  void Respond(Conn& c, std::string response) {
    c.state = State::kWriting;
    c.out = std::move(response);
    c.out_pos = 0;
    c.deadline = Clock::now() + options.response_deadline;
    epoll_event ev{};
    ev.events = EPOLLOUT;
    ev.data.u64 = c.id;
    epoll_ctl(epoll_fd, EPOLL_CTL_MOD, c.fd, &ev);
    Flush(c.id);
  }

  void Reject(Conn& c, int status, const char* code, const std::string& message) {
    stats.bad.fetch_add(1, std::memory_order_relaxed);
    Respond(c, ErrorResponse(status, code, message));
  }

  // Writes what the socket takes; when all is written, half-closes and lingers briefly so the
  // client reads the response before the close (unread input would reset it).
  void Flush(uint64_t id) {
    auto it = conns.find(id);
    if (it == conns.end()) return;
    Conn& c = it->second;
    while (c.out_pos < c.out.size()) {
      ssize_t n = ::send(c.fd, c.out.data() + c.out_pos, c.out.size() - c.out_pos, MSG_NOSIGNAL);
      if (n > 0) {
        c.out_pos += static_cast<size_t>(n);
        continue;
      }
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
      if (n < 0 && errno == EINTR) continue;
      return Close(id);
    }
    ::shutdown(c.fd, SHUT_WR);
    c.state = State::kLingering;
    c.out.clear();
    c.in.clear();
    c.deadline = std::min(c.deadline, Clock::now() + std::chrono::milliseconds(500));
    epoll_event ev{};
    ev.events = EPOLLIN;
    ev.data.u64 = c.id;
    epoll_ctl(epoll_fd, EPOLL_CTL_MOD, c.fd, &ev);
  }

  void AcceptAll() {
    const Clock::time_point now = Clock::now();
    if (now < accept_paused_until) return;
    for (;;) {
      sockaddr_storage ss{};
      socklen_t len = sizeof(ss);
      int fd = ::accept4(listen_fd, reinterpret_cast<sockaddr*>(&ss), &len,
                         SOCK_NONBLOCK | SOCK_CLOEXEC);
      if (fd < 0) {
        if (errno == EINTR || errno == ECONNABORTED) continue;
        // Out of descriptors: stop accepting for a moment instead of spinning.
        if (errno == EMFILE || errno == ENFILE || errno == ENOBUFS || errno == ENOMEM) {
          accept_paused_until = now + std::chrono::milliseconds(100);
        }
        return;
      }
      stats.accepted.fetch_add(1, std::memory_order_relaxed);
      int port = 0;
      std::string ip = IpOf(ss, &port);
      // Caps: make room by closing the oldest slow sender of this address, then of all.
      const size_t mine = per_address[ip];
      bool ok = true;
      if (mine >= options.max_per_address) {
        uint64_t victim = EvictionVictim(&ip);
        if (victim != 0) {
          stats.evicted.fetch_add(1, std::memory_order_relaxed);
          Close(victim);
        } else {
          ok = false;
        }
      }
      if (ok && conns.size() >= options.max_connections) {
        uint64_t victim = EvictionVictim(nullptr);
        if (victim != 0) {
          stats.evicted.fetch_add(1, std::memory_order_relaxed);
          Close(victim);
        } else {
          ok = false;
        }
      }
      if (!ok) {
        stats.refused.fetch_add(1, std::memory_order_relaxed);
        std::string r = ErrorResponse(503, "busy", "every connection slot is serving a request");
        (void)::send(fd, r.data(), r.size(), MSG_NOSIGNAL);
        ::close(fd);
        if (auto p = per_address.find(ip); p != per_address.end() && p->second == 0) {
          per_address.erase(p);
        }
        continue;
      }
      ++per_address[ip];
      Conn c;
      c.fd = fd;
      c.id = next_id++;
      c.ip = std::move(ip);
      c.port = port;
      c.accepted = now;
      c.deadline = now + options.request_deadline;
      epoll_event ev{};
      ev.events = EPOLLIN;
      ev.data.u64 = c.id;
      epoll_ctl(epoll_fd, EPOLL_CTL_ADD, fd, &ev);
      const uint64_t id = c.id;
      conns.emplace(id, std::move(c));
      OnReadable(id);  // the request often arrived with the connection
    }
  }

  void OnReadable(uint64_t id) {
    auto it = conns.find(id);
    if (it == conns.end()) return;
    Conn& c = it->second;
    char buf[8192];
    for (;;) {
      ssize_t n = ::recv(c.fd, buf, sizeof(buf), 0);
      if (n > 0) {
        if (c.state != State::kReading) continue;  // lingering: discard
        c.in.append(buf, static_cast<size_t>(n));
        if (!Examine(c)) return;  // answered or closed
        continue;
      }
      if (n < 0 && errno == EINTR) continue;
      if (n < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) return;
      // EOF or error: a lingering connection is done; a reading one gave up.
      return Close(id);
    }
  }

  // Checks the bytes read so far; returns true while more are needed.
  bool Examine(Conn& c) {
    if (c.request_bytes == 0) {
      const RequestHead head = ParseRequestHead(c.in, {options.max_head_bytes, options.max_headers,
                                                       options.max_body_bytes});
      if (head.outcome == RequestHead::Outcome::kNeedMore) return true;
      if (head.outcome == RequestHead::Outcome::kRefused) {
        Reject(c, head.status, head.code, head.message);
        return false;
      }
      c.request_bytes = head.request_bytes;
      const std::string& method = head.method;
      const std::string& path = head.path;
      const bool expect_continue = head.expect_continue;
      if (!options.health_path.empty() && options.health &&
          (method == "GET" || method == "HEAD") && path == options.health_path) {
        HealthAnswer a = options.health();
        stats.health.fetch_add(1, std::memory_order_relaxed);
        stats.served.fetch_add(1, std::memory_order_relaxed);
        Respond(c, JsonResponse(a.status, a.json, method == "HEAD"));
        return false;
      }
      if (expect_continue && c.in.size() < c.request_bytes) {
        static constexpr char kContinue[] = "HTTP/1.1 100 Continue\r\n\r\n";
        (void)::send(c.fd, kContinue, sizeof(kContinue) - 1, MSG_NOSIGNAL);
        c.sent_continue = true;
      }
    }
    if (c.in.size() < c.request_bytes) return true;
    c.in.resize(c.request_bytes);  // one request per connection: the rest is ignored
    {
      std::lock_guard lock(mu);
      if (jobs.size() >= options.max_queued) {
        stats.queue_full.fetch_add(1, std::memory_order_relaxed);
        Respond(c, ErrorResponse(503, "busy", "too many requests in work; retry"));
        return false;
      }
      jobs.push_back({c.id, std::move(c.in), c.ip, c.port});
    }
    cv.notify_one();
    stats.served.fetch_add(1, std::memory_order_relaxed);
    c.in.clear();
    c.state = State::kWorking;
    epoll_event ev{};
    ev.data.u64 = c.id;
    epoll_ctl(epoll_fd, EPOLL_CTL_MOD, c.fd, &ev);  // nothing to wait for until the answer
    return false;
  }

  void TakeResults() {
    uint64_t drained = 0;
    (void)!::read(wake_fd, &drained, sizeof(drained));
    std::vector<std::pair<uint64_t, std::string>> ready;
    {
      std::lock_guard lock(mu);
      ready.swap(done);
    }
    for (auto& [id, response] : ready) {
      auto it = conns.find(id);
      if (it == conns.end()) continue;
      static constexpr std::string_view kContinue = "HTTP/1.1 100 Continue\r\n\r\n";
      if (it->second.sent_continue && response.compare(0, kContinue.size(), kContinue) == 0) {
        response.erase(0, kContinue.size());
      }
      Respond(it->second, std::move(response));
    }
  }

  void ExpireDeadlines() {
    const Clock::time_point now = Clock::now();
    std::vector<uint64_t> expired;
    for (const auto& [id, c] : conns) {
      if (c.state != State::kWorking && now >= c.deadline) expired.push_back(id);
    }
    for (uint64_t id : expired) {
      Conn& c = conns.at(id);
      if (c.state == State::kReading) {
        stats.timed_out.fetch_add(1, std::memory_order_relaxed);
        std::string r = ErrorResponse(408, "request_timeout", "the request did not arrive in time");
        (void)::send(c.fd, r.data(), r.size(), MSG_NOSIGNAL);
      } else if (c.state == State::kWriting) {
        stats.timed_out.fetch_add(1, std::memory_order_relaxed);
      }
      Close(id);
    }
  }

  void GateLoop() {
    epoll_event events[64];
    Clock::time_point next_sweep = Clock::now();
    while (!stopping.load(std::memory_order_acquire)) {
      int n = epoll_wait(epoll_fd, events, 64, 20);
      for (int i = 0; i < n; ++i) {
        const uint64_t key = events[i].data.u64;
        if (key == 0) {
          AcceptAll();
        } else if (key == UINT64_MAX) {
          TakeResults();
        } else {
          auto it = conns.find(key);
          if (it == conns.end()) continue;
          if (it->second.state == State::kWriting) {
            Flush(key);
          } else {
            OnReadable(key);
          }
        }
      }
      const Clock::time_point now = Clock::now();
      if (now >= accept_paused_until && accept_paused_until != Clock::time_point{}) {
        accept_paused_until = {};
        AcceptAll();
      }
      if (now >= next_sweep) {
        ExpireDeadlines();
        next_sweep = now + std::chrono::milliseconds(20);
      }
    }
    std::vector<uint64_t> all;
    for (const auto& [id, c] : conns) all.push_back(id);
    for (uint64_t id : all) Close(id);
  }

  void WorkerLoop() {
    for (;;) {
      Job job;
      {
        std::unique_lock lock(mu);
        cv.wait(lock, [this] { return stopping.load() || !jobs.empty(); });
        if (jobs.empty()) return;
        job = std::move(jobs.front());
        jobs.pop_front();
      }
      BufferedExchange exchange(job.request, job.ip, job.port, local_ip, local_port);
      bool closed = true;
      router.process_request(exchange, /*close_connection=*/true, closed, nullptr);
      {
        std::lock_guard lock(mu);
        done.emplace_back(job.id, std::move(exchange.out()));
      }
      uint64_t one = 1;
      (void)!::write(wake_fd, &one, sizeof(one));
    }
  }
};

HttpGate::HttpGate(GateOptions options) : impl_(std::make_unique<Impl>(std::move(options))) {}

HttpGate::~HttpGate() { Stop(); }

httplib::Server& HttpGate::routes() { return impl_->router; }

Status HttpGate::Start() {
  Impl& g = *impl_;
  auto endpoint = ParseEndpoint(g.options.address);
  if (!endpoint.ok()) {
    return Status::InvalidArgument("bad HTTP address", std::string(endpoint.status().reason()));
  }
  const bool v6 = endpoint->address().is_v6();
  g.listen_fd = ::socket(v6 ? AF_INET6 : AF_INET, SOCK_STREAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  if (g.listen_fd < 0) return Status::IoError("cannot open a TCP socket", std::strerror(errno));
  int yes = 1;
  // SO_REUSEADDR only: a restart binds at once, but a second process cannot share the port.
  setsockopt(g.listen_fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof(yes));
  // The endpoint's native sockaddr (sockaddr_in or sockaddr_in6, port in network order).
  if (::bind(g.listen_fd, endpoint->data(), static_cast<socklen_t>(endpoint->size())) != 0 ||
      ::listen(g.listen_fd, 512) != 0) {
    std::string why = std::strerror(errno);
    ::close(g.listen_fd);
    g.listen_fd = -1;
    return Status::IoError("cannot bind " + g.options.address, why);
  }
  sockaddr_storage bound{};
  socklen_t blen = sizeof(bound);
  getsockname(g.listen_fd, reinterpret_cast<sockaddr*>(&bound), &blen);
  g.local_ip = IpOf(bound, &g.local_port);
  port_ = static_cast<uint16_t>(g.local_port);
  address_ = (v6 ? "[" + g.local_ip + "]" : g.local_ip) + ":" + std::to_string(port_);

  g.epoll_fd = epoll_create1(EPOLL_CLOEXEC);
  g.wake_fd = eventfd(0, EFD_NONBLOCK | EFD_CLOEXEC);
  epoll_event ev{};
  ev.events = EPOLLIN;
  ev.data.u64 = 0;
  epoll_ctl(g.epoll_fd, EPOLL_CTL_ADD, g.listen_fd, &ev);
  ev.data.u64 = UINT64_MAX;
  epoll_ctl(g.epoll_fd, EPOLL_CTL_ADD, g.wake_fd, &ev);

  for (size_t i = 0; i < std::max<size_t>(1, g.options.workers); ++i) {
    g.workers.emplace_back([&g] { g.WorkerLoop(); });
  }
  g.gate_thread = std::thread([&g] { g.GateLoop(); });
  return Status::Ok();
}

void HttpGate::Stop() {
  if (!impl_) return;
  Impl& g = *impl_;
  g.stopping.store(true, std::memory_order_release);
  g.cv.notify_all();
  if (g.gate_thread.joinable()) g.gate_thread.join();
  for (auto& w : g.workers) {
    if (w.joinable()) w.join();
  }
  g.workers.clear();
  for (int* fd : {&g.listen_fd, &g.epoll_fd, &g.wake_fd}) {
    if (*fd >= 0) ::close(*fd);
    *fd = -1;
  }
}

GateStats HttpGate::stats() const {
  const auto& s = impl_->stats;
  GateStats out;
  out.accepted = s.accepted.load(std::memory_order_relaxed);
  out.served = s.served.load(std::memory_order_relaxed);
  out.health_answers = s.health.load(std::memory_order_relaxed);
  out.evicted = s.evicted.load(std::memory_order_relaxed);
  out.refused = s.refused.load(std::memory_order_relaxed);
  out.timed_out = s.timed_out.load(std::memory_order_relaxed);
  out.bad_requests = s.bad.load(std::memory_order_relaxed);
  out.queue_full = s.queue_full.load(std::memory_order_relaxed);
  return out;
}

}  // namespace edgephys::http
