// HttpGate on loopback with raw sockets: whole-request deadline, caps, inline health, head
// checks, and requests without a body.
#include "metrics/http_gate.h"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <httplib.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <string>
#include <thread>
#include <vector>

namespace edgephys::http {
namespace {

using namespace std::chrono_literals;

int Connect(uint16_t port, const char* from = "127.0.0.1") {
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in local{};
  local.sin_family = AF_INET;
  inet_pton(AF_INET, from, &local.sin_addr);
  if (::bind(fd, reinterpret_cast<sockaddr*>(&local), sizeof(local)) != 0) return -1;
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  inet_pton(AF_INET, "127.0.0.1", &to.sin_addr);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&to), sizeof(to)) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

// Everything the server sends until it closes or `timeout` passes.
std::string ReadAll(int fd, std::chrono::milliseconds timeout = 3000ms) {
  std::string out;
  auto end = std::chrono::steady_clock::now() + timeout;
  char buf[4096];
  while (std::chrono::steady_clock::now() < end) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 50) <= 0) continue;
    ssize_t n = ::recv(fd, buf, sizeof(buf), 0);
    if (n <= 0) break;
    out.append(buf, static_cast<size_t>(n));
  }
  return out;
}

std::string Exchange(uint16_t port, const std::string& request, const char* from = "127.0.0.1") {
  int fd = Connect(port, from);
  if (fd < 0) return "connect failed";
  (void)::send(fd, request.data(), request.size(), MSG_NOSIGNAL);
  std::string r = ReadAll(fd);
  ::close(fd);
  return r;
}

class HttpGateTest : public ::testing::Test {
 protected:
  void StartGate(GateOptions o) {
    o.address = "127.0.0.1:0";
    o.health_path = "/healthz";
    o.health = [] { return HealthAnswer{200, "{\"status\":\"ok\"}"}; };
    gate_ = std::make_unique<HttpGate>(std::move(o));
    gate_->routes().Get("/slow", [](const httplib::Request&, httplib::Response& res) {
      std::this_thread::sleep_for(2s);
      res.set_content("slow", "text/plain");
    });
    gate_->routes().Post("/echo", [](const httplib::Request& req, httplib::Response& res) {
      res.set_content("body=[" + req.body + "]", "text/plain");
    });
    ASSERT_TRUE(gate_->Start().ok());
  }
  std::unique_ptr<HttpGate> gate_;
};

TEST_F(HttpGateTest, PostWithoutBodyAndWithBody) {
  StartGate({});
  EXPECT_NE(Exchange(gate_->port(), "POST /echo HTTP/1.1\r\nHost: x\r\n\r\n").find("body=[]"),
            std::string::npos);
  EXPECT_NE(Exchange(gate_->port(),
                     "POST /echo HTTP/1.1\r\nHost: x\r\nContent-Length: 3\r\n\r\nabc")
                .find("body=[abc]"),
            std::string::npos);
  EXPECT_NE(Exchange(gate_->port(), "POST /echo HTTP/1.1\r\nContent-Length: 99999999\r\n\r\n")
                .find(" 413 "),
            std::string::npos);
  EXPECT_NE(Exchange(gate_->port(), "POST /echo HTTP/1.1\r\nTransfer-Encoding: chunked\r\n\r\n")
                .find(" 411 "),
            std::string::npos);
}

TEST_F(HttpGateTest, HeadChecks) {
  StartGate({});
  std::string many = "GET /healthz HTTP/1.1\r\n";
  for (int i = 0; i < 101; ++i) many += "X-H" + std::to_string(i) + ": v\r\n";
  EXPECT_NE(Exchange(gate_->port(), many + "\r\n").find(" 431 "), std::string::npos);
  std::string nul = "GET /healthz HTTP/1.1\r\nAuthorization: Bearer k";
  nul.push_back('\0');
  EXPECT_NE(Exchange(gate_->port(), nul + "\r\n\r\n").find(" 400 "), std::string::npos);
  EXPECT_NE(Exchange(gate_->port(), "GET /healthz HTTP/1.1\r\nAuthorization: Bearer k \r\n\r\n")
                .find(" 400 "),
            std::string::npos);
  EXPECT_NE(Exchange(gate_->port(), "GET /healthz HTTP/1.1\r\n\r\n").find(" 200 "),
            std::string::npos);
}

// A client sending one byte every 300 ms is cut at the whole-request deadline (per-read
// timeouts would never fire).
TEST_F(HttpGateTest, WholeRequestDeadline) {
  GateOptions o;
  o.request_deadline = 1000ms;
  StartGate(o);
  int fd = Connect(gate_->port());
  ASSERT_GE(fd, 0);
  const std::string req = "GET /healthz HTTP/1.1\r\nX-Slow: aaaaaaaaaaaaaaaaaaaaaaaaaaaa\r\n\r\n";
  bool closed = false;
  auto start = std::chrono::steady_clock::now();
  for (size_t i = 0; i < req.size() - 2 && !closed; ++i) {
    if (::send(fd, &req[i], 1, MSG_NOSIGNAL) != 1) closed = true;
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 300) > 0) {
      std::string r = ReadAll(fd, 500ms);
      EXPECT_NE(r.find(" 408 "), std::string::npos) << r;
      closed = true;
    }
  }
  ::close(fd);
  EXPECT_TRUE(closed);
  EXPECT_LT(std::chrono::steady_clock::now() - start, 4s);
  EXPECT_GE(gate_->stats().timed_out, 1u);
}

// Slow senders fill the per-address and total caps; health and a full request still pass,
// from the attackers' own address and from another; busy workers never delay /healthz.
TEST_F(HttpGateTest, SlowSendersCannotStarve) {
  GateOptions o;
  o.max_per_address = 8;
  o.max_connections = 32;
  o.workers = 1;
  o.request_deadline = 10000ms;
  StartGate(o);
  std::vector<int> slow;
  for (int i = 0; i < 64; ++i) {
    std::string from = "127.0.0." + std::to_string(2 + i % 16);
    int fd = Connect(gate_->port(), from.c_str());
    ASSERT_GE(fd, 0);
    (void)::send(fd, "G", 1, MSG_NOSIGNAL);
    slow.push_back(fd);
  }
  std::thread busy([&] { (void)Exchange(gate_->port(), "GET /slow HTTP/1.1\r\n\r\n", "127.0.0.99"); });
  std::this_thread::sleep_for(100ms);
  for (const char* from : {"127.0.0.1", "127.0.0.2"}) {
    auto t0 = std::chrono::steady_clock::now();
    std::string r = Exchange(gate_->port(), "GET /healthz HTTP/1.1\r\n\r\n", from);
    EXPECT_NE(r.find(" 200 "), std::string::npos) << from << ": " << r;
    EXPECT_LT(std::chrono::steady_clock::now() - t0, 1s);
  }
  EXPECT_NE(Exchange(gate_->port(), "POST /echo HTTP/1.1\r\nContent-Length: 2\r\n\r\nhi", "127.0.0.3")
                .find("body=[hi]"),
            std::string::npos);
  busy.join();
  GateStats s = gate_->stats();
  EXPECT_GE(s.evicted, 64u - 32u);
  EXPECT_GE(s.health_answers, 2u);
  for (int fd : slow) ::close(fd);
}

// A request that reached its socket while the gate was busy accepting newer connections of the
// same address is served, not evicted as the oldest slow sender. The gate thread is held inside
// the health callback while the flood connects and the request is sent, so the gate meets the
// flood's connections before the request's bytes.
TEST(HttpGate, ARequestWaitingInItsSocketIsServedNotEvicted) {
  std::atomic<bool> hold{false}, held{false};
  GateOptions o;
  o.max_per_address = 4;
  o.request_deadline = 10000ms;
  o.health_path = "/healthz";
  o.health = [&] {
    held = true;
    while (hold) std::this_thread::sleep_for(1ms);
    return HealthAnswer{200, "{}"};
  };
  HttpGate gate(o);
  gate.routes().Post("/echo", [](const httplib::Request& req, httplib::Response& res) {
    res.set_content("body=[" + req.body + "]", "text/plain");
  });
  ASSERT_TRUE(gate.Start().ok());
  int early = Connect(gate.port());
  ASSERT_GE(early, 0);
  for (int i = 0; i < 200 && gate.stats().accepted < 1; ++i) std::this_thread::sleep_for(5ms);
  ASSERT_EQ(gate.stats().accepted, 1u);

  hold = true;
  std::thread stall([&] { (void)Exchange(gate.port(), "GET /healthz HTTP/1.1\r\n\r\n", "127.0.0.9"); });
  for (int i = 0; i < 400 && !held; ++i) std::this_thread::sleep_for(5ms);
  ASSERT_TRUE(held);
  std::vector<int> flood;
  for (int i = 0; i < 12; ++i) {
    int fd = Connect(gate.port());
    ASSERT_GE(fd, 0);
    (void)::send(fd, "G", 1, MSG_NOSIGNAL);
    flood.push_back(fd);
  }
  const std::string req = "POST /echo HTTP/1.1\r\nContent-Length: 2\r\n\r\nok";
  ASSERT_EQ(::send(early, req.data(), req.size(), MSG_NOSIGNAL), static_cast<ssize_t>(req.size()));
  std::this_thread::sleep_for(50ms);
  hold = false;
  stall.join();
  const std::string r = ReadAll(early);
  EXPECT_NE(r.find("body=[ok]"), std::string::npos) << "evicted with its request waiting: " << r;
  EXPECT_GE(gate.stats().evicted, 12u + 1u - 4u - 1u);
  ::close(early);
  for (int fd : flood) ::close(fd);
}

TEST(HttpGate, BindErrorsNameTheCause) {
  GateOptions o;
  o.address = "not an address";
  HttpGate bad(o);
  EXPECT_EQ(bad.Start().code(), StatusCode::kInvalidArgument);
  HttpGate first(GateOptions{});
  ASSERT_TRUE(first.Start().ok());
  GateOptions same;
  same.address = first.address();
  HttpGate second(same);
  Status st = second.Start();
  EXPECT_EQ(st.code(), StatusCode::kIoError);
  EXPECT_NE(std::string(st.reason()).find("in use"), std::string::npos) << st.ToString();
}

}  // namespace
}  // namespace edgephys::http
