// The edgephys-relay command line and config file.
//
// Options are grouped as operators look for them (network, access, rooms and limits,
// replication, physics, cluster, admin and metrics, logging). `--help` lists the ~30 options
// an operator sets; the tuning options below are not listed there but are read the same way
// from the command line and from the config file (`--config relay.toml`, one `key = value`
// line per option, the key being the option's long name without dashes). docs/operations.md
// lists every option, one line each.
#pragma once

#include <CLI/CLI.hpp>

#include <string>

#include "protocol/join_token.h"
#include "relay/cluster_hook.h"
#include "relay/relay_config.h"

namespace edgephys {

// Everything the command line sets. Defaults are the product's defaults.
struct RelayFlags {
  RelayConfig config;
  std::string bind = "0.0.0.0:7777";
  std::string metrics = "0.0.0.0:9464";     // "off": no /metrics
  std::string admin_addr = "127.0.0.1:9465";  // "off": no admin API
  bool admin_addr_given = false;            // set by Finish(): --admin-addr was passed
  std::string admin_key;                    // empty: $EDGEPHYS_ADMIN_KEY
  std::string secret;                       // empty: $EDGEPHYS_SECRET
  std::string log_level = "info";
  double run_for_s = 0;                     // 0: until a signal
  size_t io_threads = 1;
  std::string redis;                        // empty: no cluster
  ClusterOptions cluster;
  double cluster_snapshot_ms = 500;
  double cluster_heartbeat_ms = 200;
  double cluster_ttl_ms = 1000;

  // `edgephys-relay token ...`
  CLI::App* token_cmd = nullptr;
  JoinToken token;
  double token_ttl_s = 3600;
  bool token_dev_secret = false;  // sign with the built-in development secret (local tests)

  CLI::Option* admin_addr_opt = nullptr;
};

// Registers every option and the `token` subcommand on `app`, bound to `flags` (which must
// outlive the parse).
void AddRelayFlags(CLI::App& app, RelayFlags* flags);

// After a successful parse: resolves what depends on several options (replication mode).
// Returns an error naming the option at fault.
Status FinishRelayFlags(RelayFlags* flags);

}  // namespace edgephys
