// edgephys-phys: a remote PhyS worker. Attaches to a relay and simulates the rooms it assigns.
//
//   edgephys-phys --relay 127.0.0.1:7777 --worker-key $EDGEPHYS_SECRET
//   edgephys-phys --relay edgephys-relay-0.edgephys-relay:7777   # a DNS name: resolved again
//                                                                # before every attach
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <atomic>
#include <chrono>
#include <csignal>
#include <thread>

#include "client/client_endpoint.h"
#include "physics_backend/worker.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

namespace {
std::atomic<bool> g_stop{false};
void OnSignal(int) { g_stop.store(true); }

// The relay's address, resolved now (ParseEndpoint resolves host names). Called before every
// attach, so a relay that comes back at a new address under the same name (a replaced
// Kubernetes pod) is found again.
edgephys::Result<edgephys::Endpoint> ResolveRelay(const std::string& text) {
  return edgephys::ParseEndpoint(text);
}
}  // namespace

int main(int argc, char** argv) {
  using namespace edgephys;
  CLI::App app{"edgephys-phys: remote PhyS worker for an edgephys relay"};
  std::string relay = "127.0.0.1:7777", key, log_level = "info";
  double run_for_s = 0;
  bool require_packet_auth = true;
  app.add_option("--relay", relay, "Relay UDP address:port or host:port (resolved before every attach)")
      ->capture_default_str();
  app.add_option("--worker-key", key, "The relay's token secret (default: $EDGEPHYS_SECRET)");
  app.add_option("--log-level", log_level, "trace|debug|info|warn|error|off")->capture_default_str();
  app.add_option("--run-for", run_for_s, "Exit after this many seconds (0: until a signal)");
  app.add_option("--require-packet-auth", require_packet_auth,
                 "Refuse a relay that does not seal its packets (edgephys-relay --packet-auth "
                 "false); false accepts one, e.g. a test relay")
      ->capture_default_str();
  CLI11_PARSE(app, argc, argv);
  spdlog::set_level(spdlog::level::from_str(log_level));
  if (key.empty()) {
    const char* env = std::getenv("EDGEPHYS_SECRET");
    key = env != nullptr ? env : "edgephys-dev-secret";
  }
  if (relay.rfind(':') == std::string::npos || !ParseEndpoint(relay.substr(relay.rfind(':'))).ok()) {
    spdlog::error("--relay {}: expected address:port or host:port", relay);
    return 2;
  }
  std::signal(SIGINT, OnSignal);
  std::signal(SIGTERM, OnSignal);
  const auto start = std::chrono::steady_clock::now();
  auto now = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(); };
  while (!g_stop.load()) {
    auto endpoint = ResolveRelay(relay);
    if (!endpoint.ok()) {
      spdlog::warn("--relay {}: {}; retrying in 1 s", relay, endpoint.status().ToString());
      std::this_thread::sleep_for(std::chrono::seconds(1));
      continue;
    }
    auto address = endpoint->address().is_v6() ? asio::ip::make_address("::") : asio::ip::make_address("0.0.0.0");
    auto socket = UdpSocket::Open(Endpoint(address, 0));
    if (!socket.ok()) {
      spdlog::error("cannot open a UDP socket: {}", socket.status().ToString());
      return 1;
    }
    JoinToken token;
    token.room = "__workers__";
    token.player_id = static_cast<uint32_t>(SecureRandom64() | 1);
    token.permissions = kPermissionWorker;
    token.expiry_unix_s = static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                              std::chrono::system_clock::now().time_since_epoch()).count()) + 86400;
    token.nonce = SecureRandom64();
    auto signed_token = SignJoinToken(token, key);
    if (!signed_token.ok()) {
      spdlog::error("cannot sign the worker token: {}", signed_token.status().ToString());
      return 2;
    }
    PhysicsWorker worker{physics::PhysicsConfig{}};
    ClientConfig cc;
    cc.handshake_timeout_s = 3.0;
    cc.require_packet_auth = require_packet_auth;
    Client client(cc, socket->get(), &worker);
    worker.Attach(&client);
    (void)client.Connect(ToRelayAddress(*endpoint), *signed_token, now());
    while (!g_stop.load()) {
      (*socket)->WaitReadable(0.001);
      double t = now();
      client.Update(t);
      worker.Update(t);
      if (run_for_s > 0 && t >= run_for_s) g_stop.store(true);
      ClientState st = client.state();
      if (st == ClientState::kRejected) {
        spdlog::error("the relay refused the worker ({}); check --worker-key",
                      schema::EnumNameRejectReason(
                          static_cast<schema::RejectReason>(client.reject_reason())));
        return 1;
      }
      if (st == ClientState::kFailed || st == ClientState::kDisconnected) break;
    }
    if (!g_stop.load()) {
      spdlog::warn("lost the relay; reconnecting in 1 s");
      std::this_thread::sleep_for(std::chrono::seconds(1));
    }
  }
  return 0;
}
