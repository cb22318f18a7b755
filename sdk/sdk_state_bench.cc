// Per-received-state cost of a receiving client's Update(), the C++ SDK vs the C API (the C#
// binding's ClientTests.exe --bench measures the same scenario through P/Invoke). A sender moves
// N entities every frame through a real relay (tests/with_relay.sh provides EDGEPHYS_RELAY and
// two tokens); after a warm-up, the receiver's Update() calls are timed (steady clock) and
// divided by the states they delivered.
//
//   tests/with_relay.sh build/default/relay/edgephys-relay build/default/sdk/sdk_state_bench cpp 200
//   ... sdk_state_bench capi 200
//
// Prints "<mode> entities=N states=S ns_per_state=X". Run under /tmp/edgephys-bench.lock.
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <thread>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "edgephys/edgephys.h"
#include "protocol/endpoint.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

namespace {

using namespace edgephys;

double Now() { return edgephys_now_s(); }

const char* Env(const char* name) {
  const char* v = std::getenv(name);
  if (v == nullptr) {
    std::fprintf(stderr, "%s is not set (run under tests/with_relay.sh)\n", name);
    std::exit(2);
  }
  return v;
}

struct Counter : ClientListener {
  uint64_t states = 0;
  void OnEntityUpdated(const RemoteEntity&) override { ++states; }
};

// Receiver behind the C++ client, or behind the C API with a state event per state (as C#).
class Receiver {
 public:
  virtual ~Receiver() = default;
  virtual void Update(double now) = 0;
  virtual uint64_t states() const = 0;
  virtual bool joined() const = 0;
  virtual bool connected() const = 0;
  virtual void Join(const char* room) = 0;
};

class CppReceiver final : public Receiver {
 public:
  CppReceiver(const Endpoint& relay, const std::vector<uint8_t>& token)
      : socket_(std::move(*UdpSocket::Open(*ParseEndpoint("127.0.0.1:0")))), client_({}, socket_.get(), &counter_) {
    (void)client_.Connect(ToRelayAddress(relay), token, Now());
  }
  void Update(double now) override { client_.Update(now); }
  uint64_t states() const override { return counter_.states; }
  bool joined() const override { return client_.joined(); }
  bool connected() const override { return client_.state() == ClientState::kConnected; }
  void Join(const char* room) override { (void)client_.JoinRoom(room); }

 private:
  std::unique_ptr<UdpSocket> socket_;
  Counter counter_;
  Client client_;
};

class CApiReceiver final : public Receiver {
 public:
  CApiReceiver(const char* relay, const char* token) {
    edgephys_client_config cfg;
    edgephys_client_config_init(&cfg);
    cfg.queue_state_events = 1;
    edgephys_client_create(&cfg, &c_);
    edgephys_client_connect(c_, relay, token, Now());
  }
  ~CApiReceiver() override { edgephys_client_destroy(c_); }
  void Update(double now) override {
    edgephys_client_update(c_, now);
    while (edgephys_client_poll_event(c_, &ev_) == EDGEPHYS_OK && ev_.type != EDGEPHYS_EVENT_NONE) {
      if (ev_.type == EDGEPHYS_EVENT_STATE) ++states_;
    }
  }
  uint64_t states() const override { return states_; }
  bool joined() const override { return Info().joined != 0; }
  bool connected() const override { return Info().state == EDGEPHYS_STATE_CONNECTED; }
  void Join(const char* room) override { edgephys_client_join(c_, room); }

 private:
  edgephys_client_info Info() const {
    edgephys_client_info i{};
    i.struct_size = sizeof(i);
    edgephys_client_get_info(c_, &i);
    return i;
  }
  edgephys_client* c_ = nullptr;
  edgephys_event ev_{};
  uint64_t states_ = 0;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3 || (std::strcmp(argv[1], "cpp") != 0 && std::strcmp(argv[1], "capi") != 0)) {
    std::fprintf(stderr, "usage: %s cpp|capi <entities>\n", argv[0]);
    return 2;
  }
  const int entities = std::atoi(argv[2]);
  const char* relay_text = Env("EDGEPHYS_RELAY");
  const char* room = Env("EDGEPHYS_ROOM");
  auto relay = ParseEndpoint(relay_text);
  auto t1 = Base64UrlDecode(Env("EDGEPHYS_TOKEN_1"));
  if (!relay.ok() || !t1.ok()) return 2;

  auto sender_socket = std::move(*UdpSocket::Open(*ParseEndpoint("127.0.0.1:0")));
  Client sender({}, sender_socket.get());
  (void)sender.Connect(ToRelayAddress(*relay), *t1, Now());
  std::unique_ptr<Receiver> receiver;
  if (std::strcmp(argv[1], "cpp") == 0) {
    receiver = std::make_unique<CppReceiver>(*relay, *Base64UrlDecode(Env("EDGEPHYS_TOKEN_2")));
  } else {
    receiver = std::make_unique<CApiReceiver>(relay_text, Env("EDGEPHYS_TOKEN_2"));
  }
  bool asked = false;
  for (double end = Now() + 5; !(sender.joined() && receiver->joined()); ) {
    if (Now() > end) {
      std::fprintf(stderr, "no join\n");
      return 1;
    }
    sender.Update(Now());
    receiver->Update(Now());
    if (!asked && sender.state() == ClientState::kConnected && receiver->connected()) {
      (void)sender.JoinRoom(room);
      receiver->Join(room);
      asked = true;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  std::vector<uint32_t> ids;
  for (int i = 0; i < entities; ++i) ids.push_back(*sender.Spawn({.position = {float(i), 1, 0}}));

  const double warmup = 2, measure = 10, start = Now();
  double cpu_ns = 0;
  uint64_t states0 = 0;
  bool measuring = false;
  for (;;) {
    const double now = Now();
    if (now - start > warmup + measure) break;
    if (!measuring && now - start > warmup) {
      measuring = true;
      states0 = receiver->states();
      cpu_ns = 0;
    }
    const float phase = float(now - start);
    for (int i = 0; i < entities; ++i) {
      (void)sender.PublishTransform(ids[i], {float(i) + 0.5f * std::sin(phase + float(i)), 1, 0}, {});
    }
    sender.Update(now);
    const auto t0 = std::chrono::steady_clock::now();
    receiver->Update(now);
    cpu_ns += std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  const uint64_t states = receiver->states() - states0;
  std::printf("%s entities=%d states=%llu ns_per_state=%.1f\n", argv[1], entities,
              static_cast<unsigned long long>(states), states ? cpu_ns / double(states) : 0.0);
  return states > 0 ? 0 : 1;
}
