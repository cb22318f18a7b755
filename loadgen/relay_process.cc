#include "loadgen/relay_process.h"

#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>

#include "client/client_endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

namespace edgephys {

pid_t StartRelayProcess(const std::vector<std::string>& args) {
  std::vector<std::string> owned = args;
  const pid_t pid = fork();
  if (pid == 0) {
    std::vector<char*> cargs;
    for (auto& a : owned) cargs.push_back(a.data());
    cargs.push_back(nullptr);
    execv(cargs[0], cargs.data());
    _exit(127);
  }
  return pid;
}

void KillRelayProcesses(std::vector<pid_t>& pids) {
  for (pid_t p : pids) {
    if (p > 0) kill(p, SIGKILL), waitpid(p, nullptr, 0);
  }
  pids.clear();
}

std::vector<std::string> ClusterRelayArgs(const std::string& binary, const std::string& bind,
                                          const std::string& secret, int redis_port, double timeout_s,
                                          double ttl_ms, double heartbeat_ms, double snapshot_ms,
                                          int run_for_s) {
  return {binary, "--bind", bind, "--metrics", "off", "--secret", secret, "--redis",
          "127.0.0.1:" + std::to_string(redis_port), "--timeout", std::to_string(timeout_s),
          "--cluster-ttl-ms", std::to_string(ttl_ms),
          "--cluster-heartbeat-ms", std::to_string(heartbeat_ms),
          "--cluster-snapshot-ms", std::to_string(snapshot_ms),
          "--admin-addr", "off", "--log-level", "warn", "--run-for", std::to_string(run_for_s)};
}

ClusterRelays StartClusterRelays(
    int count, const std::function<std::vector<std::string>(const std::string& bind)>& args) {
  ClusterRelays relays;
  for (int i = 0; i < count; ++i) {
    const uint16_t port = FreeUdpPort();
    const std::string bind = "127.0.0.1:" + std::to_string(port);
    relays.endpoints.push_back(*ParseEndpoint(bind));
    relays.ids.push_back("127.0.0.1-" + std::to_string(port));
    relays.pids.push_back(StartRelayProcess(args(bind)));
  }
  return relays;
}

ClientConfig ClusterClientConfig(const std::vector<Endpoint>& relays) {
  ClientConfig cc;
  cc.resume = true;
  for (const Endpoint& e : relays) cc.relays.push_back(ToRelayAddress(e));
  cc.resume_attempt_s = 0.5;
  return cc;
}

std::vector<uint8_t> MintJoinToken(const std::string& secret, const std::string& room,
                                   uint32_t player_id) {
  JoinToken t;
  t.room = room;
  t.player_id = player_id;
  t.expiry_unix_s = UnixNow() + 3600;
  t.nonce = SecureRandom64();
  return *SignJoinToken(t, secret);
}

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

uint16_t FreeUdpPort() {
  auto s = UdpSocket::Open(*ParseEndpoint("127.0.0.1:0"));
  return (*s)->LocalEndpoint().port();
}

}  // namespace edgephys
