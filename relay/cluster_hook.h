// ClusterHook: a Relay's part in a cluster of relays sharing one Redis (--redis; docs/
// operations.md, "Scale-out and failover"). It is the only relay code that knows of the
// cluster; the Redis work itself runs on cluster::Directory's thread (cluster/directory.h).
//
//   - Fencing: a room is served here only while no other live relay holds it in Redis. A
//     Connect for a local copy that another live relay holds is redirected there, and the copy
//     is handed over (members sent on with kServerShutdown, so the SDK resumes at the owner)
//     once two refreshes agree. Snapshots are written only by the holder.
//   - Admission: a Connect for a room this relay does not hold is routed by the directory's
//     view: the room's live owner elsewhere gets a signed Redirect (protocol/redirect.h); an
//     unplaced room is placed (least-loaded relay) and the Connect is dropped meanwhile (the
//     client repeats it every handshake_resend_s); Redis unhealthy or the placement failed:
//     the room is served here.
//   - Every update: applies the directory's results (restores claimed rooms from their
//     snapshots), publishes the load, registers rooms created here, releases closed rooms and,
//     every snapshot_interval_s, writes each changed room's snapshot (cluster/room_snapshot.h).
//
// Thread-safety: the relay's thread only (like Relay). Never waits for Redis.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <span>
#include <string>
#include <vector>

#include "cluster/directory.h"
#include "protocol/join_token.h"

namespace edgephys {

class Relay;
class Room;

struct ClusterOptions {
  cluster::DirectoryOptions directory;
  double snapshot_interval_s = 0.5;  // bound on how old a failed-over room's state can be
};

struct ClusterCounters {
  uint64_t redirects_sent = 0;
  uint64_t connects_deferred = 0;   // dropped while the room's placement was asked
  uint64_t local_fallbacks = 0;     // admitted here because Redis was unhealthy / failed
  uint64_t rooms_restored = 0;
  uint64_t entities_restored = 0;
  uint64_t entities_skipped = 0;    // restored snapshot entries that did not verify
  uint64_t snapshots_saved = 0;
  uint64_t rooms_handed_over = 0;   // local copies dropped: another live relay holds the room
};

class ClusterHook {
 public:
  // `relay` is not owned and must outlive the hook (the Relay owns it).
  static Result<std::unique_ptr<ClusterHook>> Start(Relay* relay, const ClusterOptions& options);

  enum class Route { kLocal, kRedirected, kDeferred };
  // Where a Connect with the verified `token` goes. kRedirected: `*packet` holds the Redirect
  // datagram to send. O(log rooms).
  Route RouteConnect(const JoinToken& token, std::span<const uint8_t> token_bytes,
                     uint64_t unix_now_s, std::vector<uint8_t>* packet);
  // Once per Relay::Update, before datagrams are handled.
  void Update(double now, uint64_t unix_now_s);

  const cluster::Directory& directory() const { return *directory_; }
  const ClusterCounters& counters() const { return counters_; }

 private:
  ClusterHook(Relay* relay, const ClusterOptions& options,
              std::unique_ptr<cluster::Directory> directory);
  void Restore(const cluster::DirectoryEvent& event, double now);
  void SaveSnapshots(uint64_t unix_now_s);
  void HandOverLostRooms(double now);

  Relay* relay_;
  ClusterOptions options_;
  std::unique_ptr<cluster::Directory> directory_;
  ClusterCounters counters_;
  std::set<std::string> local_fallback_;        // rooms served here without the directory
  std::map<std::string, double> asked_;         // placement asked at (deduplication)
  std::set<std::string> known_rooms_;           // local rooms at the last update
  std::map<std::string, uint64_t> saved_sig_;   // room -> signature of the last snapshot
  std::map<std::string, double> lost_since_;   // room -> first seen held by another relay
  double next_snapshot_ = 0;
};

}  // namespace edgephys
