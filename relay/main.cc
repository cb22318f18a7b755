// edgephys-relay: the relay server process, and `edgephys-relay token` to mint join tokens.
//
//   edgephys-relay                         # UDP 0.0.0.0:7777, metrics on 0.0.0.0:9464
//   edgephys-relay --config relay.toml     # any option as a key in a TOML/INI file
//   edgephys-relay token --room lobby --player 7 --ttl 3600
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <iostream>
#include <thread>

#include "metrics/metrics_exporter.h"
#include "relay/admin/admin_http.h"
#include "relay/admin/relay_admin.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"
#include "relay/cluster_hook.h"
#include "relay/relay.h"
#include "relay/relay_flags.h"
#include "relay/relay_shards.h"

namespace {

std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop.store(true); }

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

std::string AdminKeyFromEnv(const std::string& flag) {
  if (!flag.empty()) return flag;
  const char* env = std::getenv("EDGEPHYS_ADMIN_KEY");
  return env != nullptr ? env : "";
}

std::string SecretFromEnv(const std::string& flag) {
  if (!flag.empty()) return flag;
  const char* env = std::getenv("EDGEPHYS_SECRET");
  return env != nullptr ? env : edgephys::kDevelopmentSecret;
}

}  // namespace

int main(int argc, char** argv) {
  using namespace edgephys;
  CLI::App app{"edgephys-relay: UDP relay for collaborative XR and multiplayer rooms"};
  RelayFlags flags;
  AddRelayFlags(app, &flags);
  CLI11_PARSE(app, argc, argv);
  if (Status finished = FinishRelayFlags(&flags); !finished.ok()) {
    std::fprintf(stderr, "%s\n", finished.ToString().c_str());
    return 2;
  }
  RelayConfig& config = flags.config;
  const std::string& secret = flags.secret;
  JoinToken& token = flags.token;
  const std::string& bind = flags.bind;
  const std::string& metrics = flags.metrics;
  const std::string& admin_addr = flags.admin_addr;
  const std::string& redis = flags.redis;
  const size_t io_threads = flags.io_threads;
  const double run_for_s = flags.run_for_s;
  ClusterOptions& cluster = flags.cluster;
  config.secret = SecretFromEnv(secret);
  if (*flags.token_cmd) {
    token.expiry_unix_s = UnixNow() + static_cast<uint64_t>(flags.token_ttl_s);
    token.nonce = SecureRandom64();
    auto bytes = SignJoinToken(token, config.secret);
    if (!bytes.ok()) {
      std::fprintf(stderr, "token: %s\n", std::string(bytes.status().message()).c_str());
      return 2;
    }
    std::cout << Base64UrlEncode(*bytes) << "\n";
    return 0;
  }

  spdlog::set_level(spdlog::level::from_str(flags.log_level));
  if (config.secret == kDevelopmentSecret) {
    spdlog::warn("using the built-in development secret: anyone can mint tokens. "
                 "Set --secret or EDGEPHYS_SECRET in production.");
  }
  auto endpoint = ParseEndpoint(bind);
  if (!endpoint.ok()) {
    spdlog::error("--bind {}: {}", bind, endpoint.status().message());
    return 2;
  }
  auto socket = UdpSocket::Open(*endpoint);
  if (!socket.ok()) {
    spdlog::error("cannot bind UDP {}: {}", bind, socket.status().message());
    return 1;
  }
  RelayCounters counters;
  std::unique_ptr<MetricsExporter> exporter;
  if (metrics != "off") {
    auto started = MetricsExporter::Start(metrics, &counters);
    if (!started.ok()) {
      spdlog::error("cannot serve metrics on {}: {}", metrics, started.status().message());
      return 1;
    }
    exporter = std::move(*started);
    // The port actually bound (an ephemeral one for port 0), so scripts can bind :0 and read it.
    const size_t colon = metrics.rfind(':');
    const std::string host = colon == std::string::npos ? "0.0.0.0" : metrics.substr(0, colon);
    spdlog::info("metrics on http://{}:{}/metrics", host, exporter->port());
  }
  if (io_threads > 1 && !redis.empty()) {
    spdlog::error("--redis is not supported with --io-threads > 1");
    return 2;
  }
  if (io_threads > 1) {
    if (admin_addr != "off") spdlog::warn("the admin API needs --io-threads 1; disabled");
    std::signal(SIGINT, OnSignal);
    std::signal(SIGTERM, OnSignal);
    RelayShardsOptions options;
    options.shards = io_threads;
    auto shards = RelayShards::Start(config, socket->get(), &counters, options);
    if (!shards.ok()) {
      spdlog::error("cannot start {} relay shards: {}", io_threads, shards.status().message());
      return 1;
    }
    spdlog::info("edgephys-relay listening on udp {} ({} shards)",
                 FormatEndpoint((*socket)->LocalEndpoint()), io_threads);
    const auto start = std::chrono::steady_clock::now();
    while (!g_stop.load()) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
      double now = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      if (run_for_s > 0 && now >= run_for_s) break;
    }
    spdlog::info("shutting down");
    (*shards)->Stop();
    return 0;
  }
  Relay relay(config, socket->get(), &counters);
  if (!redis.empty()) {
    auto redis_endpoint = ParseEndpoint(redis);
    if (!redis_endpoint.ok()) {
      spdlog::error("--redis {}: {}", redis, redis_endpoint.status().message());
      return 2;
    }
    cluster::DirectoryOptions& d = cluster.directory;
    d.redis_host = redis_endpoint->address().to_string();
    d.redis_port = redis_endpoint->port();
    if (d.public_address.empty()) {
      Endpoint local = (*socket)->LocalEndpoint();
      if (local.address().is_unspecified()) {
        spdlog::error("--redis needs --public-address when --bind is a wildcard address");
        return 2;
      }
      d.public_address = FormatEndpoint(local);
    }
    if (d.relay_id.empty()) {
      d.relay_id = d.public_address;
      for (char& c : d.relay_id) c = (c == ':' || c == ' ') ? '-' : c;
    }
    d.heartbeat_s = flags.cluster_heartbeat_ms / 1000.0;
    d.ttl_s = flags.cluster_ttl_ms / 1000.0;
    d.refresh_s = d.heartbeat_s;
    d.redis_timeout_s = std::min(0.5, d.ttl_s / 2);
    cluster.snapshot_interval_s = flags.cluster_snapshot_ms / 1000.0;
    Status joined = relay.EnableCluster(cluster);
    if (!joined.ok()) {
      spdlog::error("cannot join the cluster: {}", joined.ToString());
      return 2;
    }
    spdlog::info("cluster: relay '{}' at {} on redis {}", d.relay_id, d.public_address, redis);
  }
  spdlog::info("edgephys-relay listening on udp {}", FormatEndpoint((*socket)->LocalEndpoint()));
  // The admin API (docs/admin-api.md): its HTTP threads reach the relay only through
  // RelayAdmin's command queue, which the loop below drains.
  admin::RelayAdmin admin_backend(&relay, config.room_defaults);
  std::unique_ptr<admin::AdminHttpServer> admin_http;
  if (admin_addr != "off") {
    admin::AdminHttpOptions options;
    options.address = admin_addr;
    options.key = AdminKeyFromEnv(flags.admin_key);
    auto started = admin::AdminHttpServer::Start(options, &admin_backend);
    if (started.ok()) {
      admin_http = std::move(*started);
      spdlog::info("admin API on http://{}/v1 (monitor: http://{}/monitor){}", admin_http->address(),
                   admin_http->address(), options.key.empty() ? ", no key" : "");
    } else if (!flags.admin_addr_given && started.status().code() == StatusCode::kIoError) {
      // The default address is taken (another relay on this host): run without the API.
      spdlog::warn("admin API disabled: {} ({}); pass --admin-addr", started.status().ToString(),
                   admin_addr);
    } else {
      spdlog::error("admin API: {}", started.status().ToString());
      return 2;
    }
  }

  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  const auto start = std::chrono::steady_clock::now();
  auto clock = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  while (!g_stop.load()) {
    (*socket)->WaitReadable(0.002);
    double now = clock();
    relay.Update(now, UnixNow());
    admin_backend.Tick(now);
    if (admin_backend.ShouldExit()) break;  // a drain finished
    if (run_for_s > 0 && now >= run_for_s) break;
  }
  spdlog::info("shutting down");
  admin_backend.Close();  // requests waiting for the loop get 503 now, so Stop() is quick
  if (admin_http) admin_http->Stop();
  relay.Shutdown();
  return 0;
}
