#include "loadgen/ceiling.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "loadgen/stats.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"
#include "relay/relay_shards.h"

extern char** environ;

namespace edgephys::loadgen {
namespace {

using Clock = std::chrono::steady_clock;
constexpr char kSecret[] = "edgephys-loadgen-ceiling";

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + static_cast<double>(ts.tv_nsec) * 1e-9;
}

double ProcessCpuSeconds() {
  rusage u{};
  getrusage(RUSAGE_SELF, &u);
  return static_cast<double>(u.ru_utime.tv_sec + u.ru_stime.tv_sec) +
         static_cast<double>(u.ru_utime.tv_usec + u.ru_stime.tv_usec) * 1e-6;
}

// The relay under test, on its own thread(s): one Relay looped as edgephys-relay does it, or
// RelayShards.
class RelayUnderTest {
 public:
  RelayUnderTest(const RelayConfig& config, size_t io_threads) {
    socket_ = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
    if (io_threads > 1) {
      RelayShardsOptions options;
      options.shards = io_threads;
      shards_ = std::move(*RelayShards::Start(config, socket_.get(), &counters_, options));
      return;
    }
    relay_ = std::make_unique<Relay>(config, socket_.get(), &counters_);
    const auto start = Clock::now();
    thread_ = std::thread([this, start] {
      while (!stop_.load()) {
        socket_->WaitReadable(0.002);
        relay_->Update(std::chrono::duration<double>(Clock::now() - start).count(), UnixNow());
      }
      relay_->Shutdown();
    });
  }
  ~RelayUnderTest() {
    if (shards_) shards_->Stop();
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  Endpoint endpoint() const { return socket_->LocalEndpoint(); }
  const RelayCounters& counters() const { return counters_; }

 private:
  RelayCounters counters_;
  std::unique_ptr<UdpSocket> socket_;
  std::unique_ptr<Relay> relay_;
  std::unique_ptr<RelayShards> shards_;
  std::thread thread_;
  std::atomic<bool> stop_{false};
};

struct Snapshot {
  uint64_t rx = 0, tx = 0, rx_bytes = 0, tx_bytes = 0, drops = 0, rejected = 0;
  double wall = 0, process_cpu = 0, bots_cpu = 0;
  bool ok = true;
};

// An external relay's counters from its /metrics; process_cpu is the relay's (NaN unknown).
Snapshot TakeExternal(const RelayTarget& target, int relay_pid, Clock::time_point t0) {
  const RelayFigures f = target.Read();
  Snapshot s;
  s.ok = f.ok;
  auto u = [](double v) { return std::isnan(v) ? uint64_t{0} : static_cast<uint64_t>(v); };
  s.rx = u(f.packets_received);
  s.tx = u(f.packets_sent);
  s.rx_bytes = u(f.bytes_received);
  s.tx_bytes = u(f.bytes_sent);
  s.drops = u(f.io_queue_drops) + u(f.send_errors);
  s.rejected = u(f.packets_rejected);
  s.wall = std::chrono::duration<double>(Clock::now() - t0).count();
  s.process_cpu = loadgen::ProcessCpuSeconds(relay_pid);
  s.bots_cpu = ThreadCpuSeconds();
  return s;
}

Snapshot Take(const RelayCounters& c, Clock::time_point t0) {
  Snapshot s;
  s.rx = RelayCounters::Get(c.packets_received);
  s.tx = RelayCounters::Get(c.packets_sent);
  s.rx_bytes = RelayCounters::Get(c.bytes_received);
  s.tx_bytes = RelayCounters::Get(c.bytes_sent);
  s.drops = RelayCounters::Get(c.io_queue_drops) + RelayCounters::Get(c.send_errors);
  for (const auto& r : c.packets_rejected) s.rejected += RelayCounters::Get(r);
  s.wall = std::chrono::duration<double>(Clock::now() - t0).count();
  s.process_cpu = ProcessCpuSeconds();
  s.bots_cpu = ThreadCpuSeconds();
  return s;
}

struct Bot {
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<Client> client;
  std::string room;
  std::vector<uint32_t> entities;
  bool join_sent = false;
  double next_publish = 0;
};

CeilingRelayRun RunRelay(const CeilingOptions& o, size_t io_threads) {
  RelayConfig config;
  config.secret = kSecret;
  config.physics_threads = 1;
  config.room_defaults.tick_rate_hz = o.tick_rate_hz;
  config.room_defaults.capacity = 64;
  config.packet_auth = o.packet_auth;
  // Every moving entity to every other member each tick (as relay-compare does), so the egress
  // follows the tick rate rather than the priority classes' send intervals.
  config.room_defaults.replication.fixed_rate_hz = o.tick_rate_hz;
  // Every bot connects from 127.0.0.1 at once: lift the per-address limits.
  config.limits.handshakes_per_s = 0;
  config.limits.max_sessions_per_address = 0;
  const auto t0 = Clock::now();
  std::unique_ptr<RelayUnderTest> in_process;
  std::unique_ptr<RelayTarget> external;
  Endpoint endpoint;
  std::string secret = kSecret, room_prefix = "ceiling-";
  if (o.external.enabled()) {
    external = std::make_unique<RelayTarget>(o.external, t0);
    endpoint = external->endpoint();
    secret = o.external.secret;
    room_prefix = "ceiling-" + std::to_string(SecureRandom64() % 1000000000) + "-";
  } else {
    in_process = std::make_unique<RelayUnderTest>(config, io_threads);
    endpoint = in_process->endpoint();
  }
  auto take = [&] {
    return external ? TakeExternal(*external, o.external.relay_pid, t0)
                    : Take(in_process->counters(), t0);
  };
  auto now = [&] { return std::chrono::duration<double>(Clock::now() - t0).count(); };

  ClientConfig client_config;
  client_config.publish_rate_hz = o.publish_hz;
  client_config.require_packet_auth = false;  // a measurement bot: also a relay without it
  std::vector<Bot> bots(o.clients);
  for (uint32_t i = 0; i < o.clients; ++i) {
    Bot& b = bots[i];
    b.room = room_prefix + std::to_string(i % o.rooms);
    b.socket = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
    b.client = std::make_unique<Client>(client_config, b.socket.get());
    JoinToken token;
    token.room = b.room;
    token.player_id = i + 1;
    token.expiry_unix_s = UnixNow() + 600;
    token.nonce = SecureRandom64();
    (void)b.client->Connect(ToRelayAddress(endpoint), *SignJoinToken(token, secret), now());
  }
  auto pump = [&](double t) {
    for (Bot& b : bots) b.client->Update(t);
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  };
  // Connect, join and spawn: bounded by 10 s.
  const double setup_deadline = now() + 10;
  uint32_t ready = 0;
  while (now() < setup_deadline && ready < o.clients) {
    ready = 0;
    for (Bot& b : bots) {
      Client& c = *b.client;
      if (c.state() == ClientState::kConnected && !b.join_sent) {
        b.join_sent = c.JoinRoom(b.room).ok();
      }
      if (c.joined() && b.entities.empty()) {
        for (uint32_t k = 0; k < o.entities_per_client; ++k) {
          auto id = c.Spawn({.position = {0, 1, 0}, .rotation = {0, 0, 0, 1}});
          if (id.ok()) b.entities.push_back(*id);
        }
      }
      ready += !b.entities.empty();
    }
    pump(now());
  }

  // Load: every bot moves its entities on circles; the SDK sends at publish_hz.
  CeilingRelayRun run;
  run.io_threads = io_threads;
  run.clients_joined = ready;
  const double publish_period = 1.0 / o.publish_hz;
  const double load_start = now();
  const double measure_from = load_start + o.warmup_s;
  const double measure_to = measure_from + o.duration_s;
  Snapshot first{};
  bool measuring = false;
  size_t index = 0;
  for (Bot& b : bots) b.next_publish = load_start + publish_period * (index++ % 16) / 16.0;
  while (true) {
    const double t = now();
    if (!measuring && t >= measure_from) {
      first = take();
      measuring = true;
    }
    if (t >= measure_to) break;
    for (size_t i = 0; i < bots.size(); ++i) {
      Bot& b = bots[i];
      if (t < b.next_publish) continue;
      b.next_publish += publish_period;
      if (b.next_publish < t) b.next_publish = t + publish_period;
      for (size_t k = 0; k < b.entities.size(); ++k) {
        const double a = 1.7 * t + 0.37 * static_cast<double>(i * 8 + k);
        const float half = static_cast<float>(0.5 * a);
        (void)b.client->PublishTransform(
            b.entities[k],
            {static_cast<float>(std::cos(a) * 2.0), 1.0f, static_cast<float>(std::sin(a) * 2.0)},
            {0, std::sin(half), 0, std::cos(half)});
      }
    }
    pump(t);
  }
  const Snapshot last = take();
  const double seconds = last.wall - first.wall;
  if (seconds > 0 && first.ok && last.ok) {
    run.seconds = seconds;
    const double rx = static_cast<double>(last.rx - first.rx);
    const double tx = static_cast<double>(last.tx - first.tx);
    const double bytes =
        static_cast<double>(last.rx_bytes - first.rx_bytes + last.tx_bytes - first.tx_bytes);
    run.rx_packets_per_s = rx / seconds;
    run.tx_packets_per_s = tx / seconds;
    run.packets_per_s = (rx + tx) / seconds;
    run.bytes_per_s = bytes / seconds;
    run.mean_datagram_bytes = rx + tx > 0 ? bytes / (rx + tx) : 0;
    run.bots_cpu_cores = (last.bots_cpu - first.bots_cpu) / seconds;
    run.relay_cpu_cores =
        external ? (last.process_cpu - first.process_cpu) / seconds  // the relay's own process
                 : std::max(0.0, (last.process_cpu - first.process_cpu) / seconds - run.bots_cpu_cores);
    run.drops = last.drops - first.drops;
    run.rejected = last.rejected - first.rejected;
  }
  for (Bot& b : bots) b.client->Disconnect();
  pump(now());
  return run;
}

bool OnPath(const std::string& program) {
  const char* path = std::getenv("PATH");
  std::stringstream ss(path != nullptr ? path : "/usr/bin:/bin");
  std::string dir;
  while (std::getline(ss, dir, ':')) {
    if (!dir.empty() && access((dir + "/" + program).c_str(), X_OK) == 0) return true;
  }
  return false;
}

uint16_t FreeTcpPort() {
  int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  if (fd < 0) return 5201;
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  socklen_t len = sizeof(addr);
  uint16_t port = 5201;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
    port = ntohs(addr.sin_port);
  }
  ::close(fd);
  return port;
}

// Runs `command` through the shell and returns its stdout.
std::string Capture(const std::string& command) {
  std::string out;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return out;
  char buffer[4096];
  size_t n;
  while ((n = fread(buffer, 1, sizeof(buffer), pipe)) > 0) out.append(buffer, n);
  pclose(pipe);
  return out;
}

CeilingIperf RunIperf(const CeilingOptions& o, uint32_t length) {
  CeilingIperf r;
  r.length = length;
  if (!OnPath("iperf3")) {
    r.error = "iperf3 not found on PATH (scripts/setup.sh installs it): ceiling skipped";
    return r;
  }
  const uint16_t port = o.iperf_port != 0 ? o.iperf_port : FreeTcpPort();
  const std::string port_text = std::to_string(port);
  // The server: one test, then it exits. Its output is discarded.
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, 2, "/dev/null", O_WRONLY, 0);
  std::vector<std::string> args = {"iperf3", "-s", "-1", "-p", port_text};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t server = -1;
  int spawned = posix_spawnp(&server, "iperf3", &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) {
    r.error = "could not start iperf3 -s";
    return r;
  }
  const int secs = std::max(1, static_cast<int>(std::lround(o.iperf_seconds)));
  const std::string client =
      "timeout " + std::to_string(secs + 15) + " iperf3 -u -c 127.0.0.1 -p " + port_text +
      " -b 0 -l " + std::to_string(length) + " -t " + std::to_string(secs) + " --json 2>/dev/null";
  std::string text;
  nlohmann::json j;
  for (int attempt = 0; attempt < 3; ++attempt) {  // the server may not listen yet
    std::this_thread::sleep_for(std::chrono::milliseconds(300 * (attempt + 1)));
    text = Capture(client);
    j = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (!j.is_discarded() && j.contains("end") && j["end"].contains("sum_received")) break;
  }
  // Reap the server (it exits after its one test); stop it if it is still there after 3 s.
  for (int i = 0; i < 30; ++i) {
    if (waitpid(server, nullptr, WNOHANG) == server) {
      server = -1;
      break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(100));
  }
  if (server > 0) {
    kill(server, SIGTERM);
    waitpid(server, nullptr, 0);
  }
  if (j.is_discarded() || !j.contains("end") || !j["end"].contains("sum_received") ||
      !j["end"].contains("sum_sent")) {
    r.error = "iperf3 gave no usable JSON";
    if (!j.is_discarded() && j.contains("error")) r.error += ": " + j["error"].get<std::string>();
    return r;
  }
  const auto& received = j["end"]["sum_received"];
  const auto& sent = j["end"]["sum_sent"];
  const double seconds = received.value("seconds", 0.0);
  if (!(seconds > 0)) {
    r.error = "iperf3 reported no duration";
    return r;
  }
  const double packets = received.value("packets", 0.0);
  const double lost = received.value("lost_packets", 0.0);
  r.ran = true;
  r.seconds = seconds;
  r.packets_per_s = std::max(0.0, packets - lost) / seconds;
  r.bytes_per_s = received.value("bytes", 0.0) / seconds;
  r.lost_percent = received.value("lost_percent", 0.0);
  const double sent_seconds = sent.value("seconds", seconds);
  r.sent_packets_per_s = sent_seconds > 0 ? sent.value("packets", 0.0) / sent_seconds : 0;
  return r;
}

}  // namespace

std::vector<CeilingRepetition> RunCeiling(const CeilingOptions& o) {
  std::vector<CeilingRepetition> reps;
  for (uint32_t rep = 0; rep < o.repeat; ++rep) {
    CeilingRepetition r;
    double bytes = 0, packets = 0;
    for (size_t threads : o.io_threads) {
      if (o.progress) {
        std::fprintf(stderr, "ceiling: repetition %u/%u, relay --io-threads %zu...\n", rep + 1,
                     o.repeat, threads);
      }
      r.relay.push_back(RunRelay(o, threads));
      bytes += r.relay.back().bytes_per_s;
      packets += r.relay.back().packets_per_s;
    }
    uint32_t length = o.iperf_length;
    if (length == 0) {
      length = packets > 0 ? static_cast<uint32_t>(std::lround(bytes / packets)) : 200;
    }
    length = std::clamp<uint32_t>(length, 16, 65507);
    if (o.progress)
      std::fprintf(stderr, "ceiling: iperf3 -u -l %u for %g s...\n", length, o.iperf_seconds);
    r.iperf = RunIperf(o, length);
    if (!r.iperf.ran) std::fprintf(stderr, "ceiling: %s\n", r.iperf.error.c_str());
    reps.push_back(std::move(r));
  }
  return reps;
}

std::vector<CeilingSummary> SummarizeCeiling(const CeilingOptions& o,
                                             const std::vector<CeilingRepetition>& reps) {
  std::vector<CeilingSummary> out;
  for (size_t k = 0; k < o.io_threads.size(); ++k) {
    CeilingSummary s;
    s.io_threads = o.io_threads[k];
    std::vector<double> pps, bps, ipps, ibps, rp, rb, size, cpu, bots, drops, joined;
    for (const CeilingRepetition& r : reps) {
      if (k >= r.relay.size()) continue;
      const CeilingRelayRun& run = r.relay[k];
      pps.push_back(run.packets_per_s);
      bps.push_back(run.bytes_per_s);
      size.push_back(run.mean_datagram_bytes);
      if (!std::isnan(run.relay_cpu_cores)) cpu.push_back(run.relay_cpu_cores);  // NaN: unknown
      bots.push_back(run.bots_cpu_cores);
      drops.push_back(static_cast<double>(run.drops));
      joined.push_back(run.clients_joined);
      if (r.iperf.ran && r.iperf.packets_per_s > 0 && r.iperf.bytes_per_s > 0) {
        ipps.push_back(r.iperf.packets_per_s);
        ibps.push_back(r.iperf.bytes_per_s);
        rp.push_back(run.packets_per_s / r.iperf.packets_per_s);
        rb.push_back(run.bytes_per_s / r.iperf.bytes_per_s);
      }
    }
    s.packets_per_s = Median(pps);
    s.bytes_per_s = Median(bps);
    s.iperf_packets_per_s = Median(ipps);
    s.iperf_bytes_per_s = Median(ibps);
    s.ratio_packets = Median(rp);
    s.ratio_bytes = Median(rb);
    s.mean_datagram_bytes = Median(size);
    s.relay_cpu_cores = cpu.empty() && !reps.empty() && o.external.enabled() ? kUnknown : Median(cpu);
    s.bots_cpu_cores = Median(bots);
    s.drops = static_cast<uint64_t>(Median(drops));
    s.clients_joined = static_cast<uint32_t>(Median(joined));
    out.push_back(s);
  }
  return out;
}

}  // namespace edgephys::loadgen
