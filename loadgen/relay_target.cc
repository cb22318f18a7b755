#include "loadgen/relay_target.h"

#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <asio.hpp>
#include <fstream>
#include <sstream>

#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"

namespace edgephys::loadgen {
namespace {

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch()).count());
}

double ThreadCpuSeconds() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

// "host:port" -> the metrics address: "" gives the relay's host with port 9464.
std::string MetricsAddress(const ExternalRelayOptions& o) {
  if (!o.metrics.empty()) return o.metrics;
  auto ep = ParseEndpoint(o.relay);
  if (!ep.ok()) return "";
  const asio::ip::address a = ep->address();
  return (a.is_v6() ? "[" + a.to_string() + "]" : a.to_string()) + ":9464";
}

}  // namespace

void AddExternalRelayOptions(CLI::App& cmd, ExternalRelayOptions* o) {
  cmd.add_option("--relay", o->relay,
                 "Use an external edgephys-relay at HOST:PORT instead of starting one in-process");
  cmd.add_option("--secret", o->secret, "Join token secret of the external relay (with --relay)");
  cmd.add_option("--metrics", o->metrics,
                 "The external relay's Prometheus HOST:PORT (default: its host, port 9464; "
                 "'off': no server-side figures)");
  cmd.add_option("--relay-pid", o->relay_pid,
                 "PID of the external relay, for its CPU from /proc (else CPU is unknown)");
}

std::string ValidateExternalRelay(const ExternalRelayOptions& o) {
  if (!o.enabled()) {
    if (!o.secret.empty() || !o.metrics.empty() || o.relay_pid != 0) {
      return "--secret, --metrics and --relay-pid need --relay";
    }
    return "";
  }
  if (auto ep = ParseEndpoint(o.relay); !ep.ok()) {
    return "--relay: " + ep.status().ToString();
  }
  if (o.secret.empty()) return "--relay needs --secret (the relay's join token secret)";
  if (o.metrics != "off") {
    if (auto ep = ParseEndpoint(MetricsAddress(o)); !ep.ok()) {
      return "--metrics: " + ep.status().ToString();
    }
  }
  if (o.relay_pid < 0) return "--relay-pid must be positive";
  return "";
}

std::string HttpGet(const std::string& host_port, const std::string& path, double timeout_s,
                    std::string* error) {
  auto ep = ParseEndpoint(host_port);
  if (!ep.ok()) {
    *error = "bad address " + host_port;
    return "";
  }
  try {
    asio::io_context io;
    asio::ip::tcp::socket socket(io);
    socket.open(ep->address().is_v6() ? asio::ip::tcp::v6() : asio::ip::tcp::v4());
    timeval tv{};
    tv.tv_sec = static_cast<time_t>(timeout_s);
    tv.tv_usec = static_cast<suseconds_t>((timeout_s - static_cast<double>(tv.tv_sec)) * 1e6);
    setsockopt(socket.native_handle(), SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
    setsockopt(socket.native_handle(), SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
    socket.connect(asio::ip::tcp::endpoint(ep->address(), ep->port()));
    const std::string request = "GET " + path + " HTTP/1.0\r\nHost: " + host_port +
                                "\r\nAccept: text/plain\r\nConnection: close\r\n\r\n";
    asio::write(socket, asio::buffer(request));
    std::string response;
    std::array<char, 16384> buf;
    asio::error_code ec;
    for (size_t reads = 0; reads < 4096; ++reads) {  // bounded: 64 MB at most
      size_t n = socket.read_some(asio::buffer(buf), ec);
      response.append(buf.data(), n);
      if (ec) break;
    }
    if (ec && ec != asio::error::eof) {
      *error = "read: " + ec.message();
      return "";
    }
    const size_t header_end = response.find("\r\n\r\n");
    if (header_end == std::string::npos || response.compare(0, 5, "HTTP/") != 0) {
      *error = "not an HTTP response";
      return "";
    }
    const size_t sp = response.find(' ');
    if (sp == std::string::npos || response.compare(sp + 1, 3, "200") != 0) {
      *error = "HTTP status " + response.substr(0, response.find("\r\n"));
      return "";
    }
    return response.substr(header_end + 4);
  } catch (const std::exception& e) {
    *error = e.what();
    return "";
  }
}

std::map<std::string, double> ParsePrometheusText(const std::string& text) {
  std::map<std::string, double> out;
  std::istringstream in(text);
  std::string line;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#') continue;
    // name{labels} value [timestamp]; label values may hold spaces, so split after '}'.
    size_t name_end = line.find('}');
    name_end = name_end == std::string::npos ? line.find(' ') : name_end + 1;
    if (name_end == std::string::npos || name_end >= line.size()) continue;
    std::istringstream value(line.substr(name_end));
    std::string v;
    if (!(value >> v)) continue;
    double d;
    if (v == "+Inf") d = std::numeric_limits<double>::infinity();
    else if (v == "-Inf") d = -std::numeric_limits<double>::infinity();
    else if (v == "NaN") d = kUnknown;
    else {
      try {
        d = std::stod(v);
      } catch (...) {
        continue;
      }
    }
    out[line.substr(0, name_end)] = d;
  }
  return out;
}

double SumSeries(const std::map<std::string, double>& series, const std::string& name) {
  double sum = 0;
  bool any = false;
  for (auto it = series.lower_bound(name); it != series.end(); ++it) {
    const std::string& key = it->first;
    if (key.compare(0, name.size(), name) != 0) break;
    if (key.size() != name.size() && key[name.size()] != '{') continue;
    sum += it->second;
    any = true;
  }
  return any ? sum : kUnknown;
}

double ProcessCpuSeconds(int pid) {
  if (pid <= 0) return kUnknown;
  std::ifstream f("/proc/" + std::to_string(pid) + "/stat");
  std::string stat;
  if (!std::getline(f, stat)) return kUnknown;
  // Fields after the command (which may hold spaces) start after the last ')'.
  const size_t close = stat.rfind(')');
  if (close == std::string::npos) return kUnknown;
  std::istringstream rest(stat.substr(close + 2));
  std::string field;
  double utime = 0, stime = 0;
  // rest starts at field 3 (state); utime is field 14, stime 15.
  for (int i = 3; i <= 15 && rest >> field; ++i) {
    if (i == 14) utime = std::stod(field);
    if (i == 15) stime = std::stod(field);
  }
  return (utime + stime) / static_cast<double>(sysconf(_SC_CLK_TCK));
}

RelayThread::RelayThread(const RelayConfig& config, std::chrono::steady_clock::time_point t0)
    : start(t0) {
  socket = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
  relay = std::make_unique<Relay>(config, socket.get(), &counters);
  thread = std::thread([this] {
    while (!stop.load()) {
      socket->WaitReadable(0.001);
      double now = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      relay->Update(now, UnixNow());
      cpu_s.store(ThreadCpuSeconds());
    }
    relay->Shutdown();
  });
}

RelayThread::~RelayThread() {
  stop.store(true);
  thread.join();
}

RelayTarget::RelayTarget(const RelayConfig& config, std::chrono::steady_clock::time_point t0)
    : thread_(std::make_unique<RelayThread>(config, t0)), secret_(config.secret), t0_(t0) {
  endpoint_ = thread_->socket->LocalEndpoint();
}

RelayTarget::RelayTarget(const ExternalRelayOptions& options,
                         std::chrono::steady_clock::time_point t0)
    : external_(options), secret_(options.secret), t0_(t0) {
  endpoint_ = *ParseEndpoint(options.relay);
  external_.metrics = options.metrics == "off" ? "off" : MetricsAddress(options);
}

RelayTarget::~RelayTarget() = default;

std::vector<uint8_t> RelayTarget::Token(const std::string& room, uint32_t player_id) const {
  return MintJoinToken(secret_, room, player_id);
}

RelayFigures RelayTarget::Read() const {
  RelayFigures f;
  f.t = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0_).count();
  if (thread_) {
    const RelayCounters& c = thread_->counters;
    f.ok = true;
    f.bytes_sent = static_cast<double>(c.bytes_sent.load());
    f.bytes_received = static_cast<double>(c.bytes_received.load());
    f.packets_sent = static_cast<double>(c.packets_sent.load());
    f.packets_received = static_cast<double>(c.packets_received.load());
    f.entity_updates_sent = static_cast<double>(c.entity_updates_sent.load());
    f.reliable_resends = static_cast<double>(c.reliable_resends.load());
    f.physics_steps = static_cast<double>(c.physics_steps.load());
    f.physics_step_seconds_sum = c.physics_step_seconds.sum();
    uint64_t n = 0;
    for (size_t i = 0; i <= 10; ++i) n += c.physics_step_seconds.bucket(i);
    f.physics_step_count = static_cast<double>(n);
    f.io_queue_drops = static_cast<double>(c.io_queue_drops.load());
    f.send_errors = static_cast<double>(c.send_errors.load());
    for (const auto& r : c.packets_rejected) f.packets_rejected += static_cast<double>(r.load());
    f.rooms = static_cast<double>(c.rooms.load());
    f.clients = static_cast<double>(c.clients.load());
    f.cpu_s = thread_->cpu_s.load();
    return f;
  }
  f.cpu_s = ProcessCpuSeconds(external_.relay_pid);
  if (external_.metrics == "off") {
    f.error = "--metrics off";
    return f;
  }
  std::string error;
  const std::string body = HttpGet(external_.metrics, "/metrics", 2.0, &error);
  if (body.empty()) {
    f.error = "GET http://" + external_.metrics + "/metrics: " + (error.empty() ? "empty" : error);
    return f;
  }
  const auto s = ParsePrometheusText(body);
  auto get = [&](const char* name) { return SumSeries(s, name); };
  f.bytes_sent = get("edgephys_bytes_sent_total");
  f.bytes_received = get("edgephys_bytes_received_total");
  f.packets_sent = get("edgephys_packets_sent_total");
  f.packets_received = get("edgephys_packets_received_total");
  f.entity_updates_sent = get("edgephys_entity_updates_sent_total");
  f.reliable_resends = get("edgephys_reliable_resends_total");
  f.physics_steps = get("edgephys_physics_steps_total");
  f.physics_step_seconds_sum = get("edgephys_physics_step_seconds_sum");
  f.physics_step_count = get("edgephys_physics_step_seconds_count");
  f.io_queue_drops = get("edgephys_io_queue_drops_total");
  f.send_errors = get("edgephys_send_errors_total");
  f.packets_rejected = get("edgephys_packets_rejected_total");
  f.rooms = get("edgephys_rooms");
  f.clients = get("edgephys_clients");
  f.ok = !std::isnan(f.bytes_sent);
  if (!f.ok) f.error = "no edgephys_bytes_sent_total in the scrape";
  return f;
}

std::string RelayTarget::cpu_source() const {
  if (thread_) return "relay thread";
  if (external_.relay_pid > 0) return "/proc/" + std::to_string(external_.relay_pid) + "/stat";
  return "unknown";
}

nlohmann::json ExternalRelayJson(const ExternalRelayOptions& options) {
  return {{"external", true},
          {"address", options.relay},
          {"metrics", options.metrics.empty() ? "(relay host):9464" : options.metrics},
          {"cpu_source", options.relay_pid > 0 ? "/proc/<pid>/stat" : "unknown"}};
}

const char* ExternalRelayCpuNote(const ExternalRelayOptions& options) {
  return options.relay_pid > 0 ? "process CPU (all threads) from /proc/<pid>/stat"
                               : "null: the exporter has no process CPU series; pass --relay-pid";
}

nlohmann::json RelayTarget::Describe() const {
  if (thread_) return {{"external", false}};
  return {{"external", true},
          {"address", external_.relay},
          {"metrics", external_.metrics},
          {"cpu_source", cpu_source()},
          {"note",
           "server-side figures are differences of the relay's /metrics counters (edgephys_*), "
           "process-wide: they include any other traffic the relay carries; CPU from "
           "/proc/<pid>/stat with --relay-pid, else null"}};
}

}  // namespace edgephys::loadgen
