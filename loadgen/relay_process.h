// Child relay processes for the cluster benchmarks: start one edgephys-relay binary with a
// given argv, and stop a set of them; the free port and wall-clock second they are started
// with, and the join tokens their clients present. Single-threaded use; the caller owns the
// pids.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "client/client.h"
#include "protocol/endpoint.h"

namespace edgephys {

// fork + execv(args[0], args). Returns the child's pid, or -1 if fork failed. A child whose
// exec fails exits with status 127.
pid_t StartRelayProcess(const std::vector<std::string>& args);

// SIGKILL and reap every pid > 0 in `pids`, then clear it. Bounded: waitpid after SIGKILL.
void KillRelayProcesses(std::vector<pid_t>& pids);

// The argv of one edgephys-relay of a Redis cluster: `binary` bound to `bind` ("host:port"),
// `secret`, Redis on 127.0.0.1:`redis_port`, client --timeout `timeout_s`, cluster TTL,
// heartbeat and snapshot periods in ms; metrics and admin off, warn logs, exits after run_for_s.
std::vector<std::string> ClusterRelayArgs(const std::string& binary, const std::string& bind,
                                          const std::string& secret, int redis_port, double timeout_s,
                                          double ttl_ms, double heartbeat_ms, double snapshot_ms,
                                          int run_for_s);

// Relays of a Redis cluster started as child processes on free loopback ports.
struct ClusterRelays {
  std::vector<pid_t> pids;          // the caller stops them (KillRelayProcesses)
  std::vector<Endpoint> endpoints;  // 127.0.0.1:<port>
  std::vector<std::string> ids;     // their cluster ids, "127.0.0.1-<port>"
};

// Starts `count` relays, each with the argv `args(bind)` for its bind address
// "127.0.0.1:<port>" (e.g. ClusterRelayArgs). A relay that could not be forked has pid -1.
ClusterRelays StartClusterRelays(
    int count, const std::function<std::vector<std::string>(const std::string& bind)>& args);

// A client of the cluster that resumes its session through any of `relays`, retrying every
// 0.5 s.
ClientConfig ClusterClientConfig(const std::vector<Endpoint>& relays);

// A join token for `player_id` in `room`, valid for an hour, signed with `secret` (the load
// generator's bots and the cluster benchmarks' clients alike).
std::vector<uint8_t> MintJoinToken(const std::string& secret, const std::string& room,
                                   uint32_t player_id);

// Seconds since the Unix epoch, system clock (join-token expiry times).
uint64_t UnixNow();

// A UDP port on 127.0.0.1 that was free a moment ago (bound to port 0, read, closed); another
// process may take it before the caller binds it.
uint16_t FreeUdpPort();

}  // namespace edgephys
