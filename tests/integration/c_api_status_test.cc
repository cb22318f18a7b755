// edgephys_client_get_connection_status against a real relay on loopback UDP, through a proxy
// that delays, drops and (for a while) black-holes datagrams: the figures a game's network HUD
// shows must follow what the path does.
#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <cstdio>
#include <deque>
#include <functional>
#include <string>

#include "edgephys/edgephys.h"
#include "protocol/join_token.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

// A UDP proxy between one client and the relay, pumped from the test thread. Client->relay
// datagrams can be dropped (every Nth, or all while black-holed); both directions can be
// delayed by a fixed time.
class Proxy {
 public:
  explicit Proxy(uint16_t relay_port) {
    fd_ = socket(AF_INET, SOCK_DGRAM, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(fd_, reinterpret_cast<sockaddr*>(&a), sizeof(a));
    socklen_t n = sizeof(a);
    getsockname(fd_, reinterpret_cast<sockaddr*>(&a), &n);
    port_ = ntohs(a.sin_port);
    fcntl(fd_, F_SETFL, O_NONBLOCK);
    relay_.sin_family = AF_INET;
    relay_.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    relay_.sin_port = htons(relay_port);
  }
  ~Proxy() { close(fd_); }

  std::string address() const { return "127.0.0.1:" + std::to_string(port_); }
  void set_drop_every(int n) { drop_every_ = n; }
  void set_delay(double s) { delay_s_ = s; }
  void set_blackhole(bool on) { blackhole_ = on; }
  uint64_t dropped() const { return dropped_; }

  void Pump(double now) {
    for (int i = 0; i < 256; ++i) {  // bounded per pump
      sockaddr_in from{};
      socklen_t n = sizeof(from);
      Datagram d;
      ssize_t got = recvfrom(fd_, d.bytes, sizeof(d.bytes), 0, reinterpret_cast<sockaddr*>(&from), &n);
      if (got <= 0) break;
      d.size = static_cast<size_t>(got);
      d.due = now + delay_s_;
      const bool from_relay = from.sin_port == relay_.sin_port;
      if (from_relay) {
        if (!have_client_) continue;
        d.to = client_;
      } else {
        client_ = from;
        have_client_ = true;
        ++from_client_;
        if (blackhole_ || (drop_every_ > 0 && from_client_ % drop_every_ == 0)) {
          ++dropped_;
          continue;
        }
        d.to = relay_;
      }
      queue_.push_back(d);
    }
    while (!queue_.empty() && queue_.front().due <= now) {
      const Datagram& d = queue_.front();
      sendto(fd_, d.bytes, d.size, 0, reinterpret_cast<const sockaddr*>(&d.to), sizeof(d.to));
      queue_.pop_front();
    }
  }

 private:
  struct Datagram {
    unsigned char bytes[2048];
    size_t size = 0;
    double due = 0;
    sockaddr_in to{};
  };
  int fd_ = -1;
  uint16_t port_ = 0;
  sockaddr_in relay_{}, client_{};
  bool have_client_ = false;
  int drop_every_ = 0;
  double delay_s_ = 0;
  bool blackhole_ = false;
  uint64_t from_client_ = 0, dropped_ = 0;
  std::deque<Datagram> queue_;
};

std::string Describe(const edgephys_connection_status& s) {
  char text[256];
  std::snprintf(text, sizeof(text),
                "rtt %.1f ms, loss %.3f, send %.0f B/s %.1f pkt/s, receive %.0f B/s %.1f pkt/s, "
                "resends %llu, pending %llu B",
                s.rtt_s * 1e3, s.loss, s.send_bytes_per_s, s.send_packets_per_s,
                s.receive_bytes_per_s, s.receive_packets_per_s,
                static_cast<unsigned long long>(s.reliable_resends),
                static_cast<unsigned long long>(s.pending_reliable_bytes));
  return text;
}

class CApiStatus : public ::testing::Test {
 protected:
  void SetUp() override {
    proxy_ = std::make_unique<Proxy>(world_.relay_endpoint().port());
    edgephys_client_config cfg;
    ASSERT_EQ(edgephys_client_config_init(&cfg), EDGEPHYS_OK);
    cfg.bind_address = "127.0.0.1:0";
    cfg.publish_rate_hz = 60;
    ASSERT_EQ(edgephys_client_create(&cfg, &c_), EDGEPHYS_OK) << edgephys_last_error();
    const std::string token = Base64UrlEncode(MintToken("hud", 7));
    ASSERT_EQ(edgephys_client_connect(c_, proxy_->address().c_str(), token.c_str(), world_.Now()),
              EDGEPHYS_OK)
        << edgephys_last_error();
  }
  void TearDown() override { edgephys_client_destroy(c_); }

  void Step() {
    world_.Step();
    const double now = world_.Now();
    proxy_->Pump(now);
    ASSERT_EQ(edgephys_client_update(c_, now), EDGEPHYS_OK);
    edgephys_event ev;
    while (edgephys_client_poll_event(c_, &ev) == EDGEPHYS_OK && ev.type != EDGEPHYS_EVENT_NONE) {
      if (ev.type == EDGEPHYS_EVENT_CONNECTED) edgephys_client_join(c_, "hud");
      if (ev.type == EDGEPHYS_EVENT_JOINED) joined_ = true;
    }
    if (entity_ != 0) {  // a hand that keeps moving, published at the client's 60 Hz
      edgephys_transform t{{static_cast<float>(0.1 * now), 1, 0}, {0, 0, 0, 1}};
      edgephys_client_publish_transform(c_, entity_, &t);
    }
  }
  void RunFor(double s) {
    const double end = world_.Now() + s;
    while (world_.Now() < end) Step();
  }
  bool RunUntil(const std::function<bool()>& done, double timeout_s) {
    const double end = world_.Now() + timeout_s;
    while (world_.Now() < end && !done()) Step();
    return done();
  }
  void JoinAndSpawn() {
    ASSERT_TRUE(RunUntil([&] { return joined_; }, 5.0));
    entity_ = Spawn();
  }
  uint32_t Spawn() {
    edgephys_spawn_desc d;
    edgephys_spawn_desc_init(&d);
    uint32_t id = 0;
    EXPECT_EQ(edgephys_client_spawn(c_, &d, &id), EDGEPHYS_OK) << edgephys_last_error();
    return id;
  }
  edgephys_connection_status Status() {
    edgephys_connection_status st{};
    st.struct_size = sizeof(st);
    EXPECT_EQ(edgephys_client_get_connection_status(c_, &st), EDGEPHYS_OK) << edgephys_last_error();
    return st;
  }

  LoopbackWorld world_;
  std::unique_ptr<Proxy> proxy_;
  edgephys_client* c_ = nullptr;
  bool joined_ = false;
  uint32_t entity_ = 0;
};

TEST_F(CApiStatus, ACleanPathShowsLowRttNoLossAndRatesThatMatchTheCounters) {
  JoinAndSpawn();
  RunFor(1.5);
  const edgephys_connection_status a = Status();
  const double ta = world_.Now();
  RunFor(1.0);
  const edgephys_connection_status b = Status();
  const double tb = world_.Now();
  SCOPED_TRACE(Describe(b));
  EXPECT_EQ(b.state, static_cast<uint32_t>(EDGEPHYS_STATE_CONNECTED));
  EXPECT_GT(b.rtt_s, 0.0);
  EXPECT_LT(b.rtt_s, 0.06);  // loopback + the relay's ack hold (20 ms) + pump steps
  EXPECT_LT(b.loss, 0.03);
  // The windowed rates against the counters' own difference over the same second.
  const double sent_bps = static_cast<double>(b.bytes_sent - a.bytes_sent) / (tb - ta);
  const double recv_pps = static_cast<double>(b.packets_received - a.packets_received) / (tb - ta);
  EXPECT_NEAR(b.send_bytes_per_s, sent_bps, 0.25 * sent_bps);
  EXPECT_NEAR(b.receive_packets_per_s, recv_pps, 0.25 * recv_pps + 2);
  EXPECT_GT(b.send_packets_per_s, 40);   // a 60 Hz publish
  EXPECT_LT(b.send_packets_per_s, 130);  // ... plus acks, not per-update floods
  EXPECT_GT(b.reliable_delivered, 0u);   // Joined, the spawn's answer
  EXPECT_EQ(b.pending_reliable_bytes, 0u);
  EXPECT_EQ(b.reserved, 0u);
  std::printf("clean path: %s\n", Describe(b).c_str());
}

TEST_F(CApiStatus, LossDelayAndABlackHoleShowInLossRttAndPendingReliableBytes) {
  proxy_->set_delay(0.04);  // 40 ms each way
  JoinAndSpawn();
  proxy_->set_drop_every(4);  // 25 % of the client's datagrams never reach the relay
  RunFor(3.0);
  edgephys_connection_status st = Status();
  std::printf("lossy path: %s\n", Describe(st).c_str());
  EXPECT_GE(st.rtt_s, 0.075);
  EXPECT_LT(st.rtt_s, 0.2);
  EXPECT_GT(st.loss, 0.10) << "proxy dropped " << proxy_->dropped();
  EXPECT_LT(st.loss, 0.45);

  // The relay stops hearing us: a reliable message waits, is resent, and shows as pending.
  proxy_->set_drop_every(0);
  proxy_->set_blackhole(true);
  const uint64_t resends_before = st.reliable_resends;
  (void)Spawn();
  RunFor(1.0);
  st = Status();
  std::printf("black hole: %s\n", Describe(st).c_str());
  EXPECT_GT(st.pending_reliable_bytes, 0u);
  EXPECT_GT(st.reliable_resends, resends_before);
  proxy_->set_blackhole(false);
  EXPECT_TRUE(RunUntil([&] { return Status().pending_reliable_bytes == 0; }, 3.0));
}

}  // namespace
}  // namespace edgephys::testing
