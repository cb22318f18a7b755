// edgephys-cluster-failover --fault kill-during-spawns: the "nothing lost silently" check of a
// failover (issue 35). Starts a real redis-server and `relays` edgephys-relay processes on free
// loopback ports; `spawners` players and one observer join one room (on its owner, through
// redirects); every spawner spawns a Persistent entity every `spawn_period_s`; `kill_after_s`
// in, the room's owner (Redis) is killed with SIGKILL while the spawns go on; every player
// resumes on a live relay (ClientConfig::resume). Then every id each spawner's Spawn()
// returned must either still be owned by it and exist at every other player (the observer
// included), or have been reported lost to it (OnError "lost in failover: ..."). Prints the
// counts as JSON (spawned, restored from the snapshot, re-spawned, reported lost, silently
// lost); returns 0 if nothing was lost silently, 1 otherwise. Bounded: every phase has a
// deadline; the processes it started are killed by PID before it returns.
#pragma once

#include <string>

namespace edgephys {

struct SpawnBurstOptions {
  std::string relay_binary;
  int relays = 2;
  int spawners = 4;
  double spawn_period_s = 0.04;
  double kill_after_s = 2.0;
  double recover_timeout_s = 12.0;  // kill until every player has resumed
  double settle_s = 4.0;            // at most, until every surviving entity is seen everywhere
  double relay_timeout_s = 1.0;     // relays' --timeout (also the clients' connection timeout)
  double ttl_ms = 1000, heartbeat_ms = 200, snapshot_ms = 500;
  std::string json_path;
};

int RunKillDuringSpawns(const SpawnBurstOptions& options);

}  // namespace edgephys
