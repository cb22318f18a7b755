// Directory: this relay's membership in a cluster of relays that share one Redis
// (docs/operations.md, "Scale-out and failover"). It
//   - registers the relay (id, public UDP address, load, draining) with a heartbeat: the key
//     edgephys:relay:<id> is SET with a TTL (PX) every heartbeat, so a relay that dies drops
//     out of the cluster when its TTL runs out. Liveness is that key alone: a relay missing
//     from the relay set, or whose entry was overwritten with garbage, is still alive (and
//     its rooms unclaimable) while its key exists;
//   - places rooms: a room lives on exactly one relay, edgephys:room:<name> = relay id, set
//     atomically (a Lua get-or-set) so two relays never both own a room; a new room goes to
//     the least-loaded live, non-draining relay;
//   - keeps a view (live relays, room owners) refreshed every refresh_s for routing;
//   - fails over: a room whose owner is no longer live is claimed by one live relay (chosen by
//     a hash of the room over the sorted live relays, claimed with a Lua compare-and-set), and
//     its last snapshot (edgephys:state:<name>, written by its owner every few hundred ms) is
//     handed to the claimer to restore.
//
// All Redis I/O runs on the directory's own thread: the public methods only queue work or copy
// results under a short mutex, and never wait for Redis. Redis down or slow: calls time out
// (redis_timeout_s), are counted in counters().redis_errors, the view turns unhealthy and the
// caller keeps serving what it has. Garbage in any key (wrong type, bad JSON, a snapshot that
// does not decode) is counted in counters().bad_keys and skipped, never a crash.
//
// Thread-safety: every public method is thread-safe. The destructor stops the thread (bounded
// by one Redis timeout).
#pragma once

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <vector>

#include "cluster/room_snapshot.h"
#include "protocol/status.h"

namespace edgephys::cluster {

class RedisClient;

struct DirectoryOptions {
  std::string redis_host = "127.0.0.1";
  uint16_t redis_port = 6379;
  std::string relay_id;        // unique in the cluster; non-empty, no ':' or spaces
  std::string public_address;  // host:port clients use to reach this relay (redirects)
  double heartbeat_s = 0.2;    // registration refreshed this often
  double ttl_s = 1.0;          // registration expires after this long without a heartbeat
  double refresh_s = 0.2;      // view (relays, room owners) re-read this often
  double redis_timeout_s = 0.5;  // bound on every Redis round trip
  std::string key_prefix = "edgephys:";
};

struct RelayInfo {
  std::string id;
  std::string address;
  uint32_t users = 0;
  uint32_t rooms = 0;
  bool draining = false;
};

// A consistent copy of what the directory last read from Redis (immutable once published).
struct DirectoryView {
  bool healthy = false;  // the last refresh succeeded recently
  std::map<std::string, RelayInfo> relays;            // live relays by id
  std::map<std::string, std::string> room_owner;      // room -> relay id (live or not)
  // Relays whose heartbeat key lives but holds garbage (counted in bad_keys): not dead, so
  // their rooms are not claimed, but never placed on or redirected to.
  std::set<std::string> unroutable;
  // The live relay owning `room`, null if unknown or its owner is not live.
  const RelayInfo* OwnerOf(const std::string& room) const;
};

struct DirectoryEvent {
  enum class Kind {
    kPlaced,           // `room` is placed on `owner` (maybe this relay)
    kPlacementFailed,  // Redis unreachable or the room's key is garbage
    kClaimed,          // this relay took over `room` from a dead relay; restore `snapshot`
  };
  Kind kind = Kind::kPlaced;
  std::string room;
  std::string owner;
  bool has_snapshot = false;  // kClaimed: false when no (valid) snapshot was stored
  RoomSnapshot snapshot;
};

struct DirectoryCounters {
  std::atomic<uint64_t> redis_errors{0};   // failed round trips (down, timeout, protocol)
  std::atomic<uint64_t> bad_keys{0};       // garbage met in Redis keys
  std::atomic<uint64_t> placements{0};     // rooms placed (by this relay's requests)
  std::atomic<uint64_t> claims{0};         // rooms claimed from dead relays
  std::atomic<uint64_t> snapshots_written{0};
  std::atomic<uint64_t> snapshot_bytes_written{0};
  std::atomic<uint64_t> heartbeats{0};
};

class Directory {
 public:
  // Starts the directory thread. kInvalidArgument for a bad id or address; Redis need not be
  // up (the thread keeps retrying).
  static Result<std::unique_ptr<Directory>> Start(const DirectoryOptions& options);
  ~Directory();
  Directory(const Directory&) = delete;
  Directory& operator=(const Directory&) = delete;

  const std::string& relay_id() const { return options_.relay_id; }
  // The load published with the next heartbeat.
  void SetLoad(uint32_t users, uint32_t rooms, bool draining);
  // Places `room` (get-or-set): an event kPlaced or kPlacementFailed follows. With
  // `prefer_self` the room is placed on this relay if it has no owner yet (a room that already
  // exists here); otherwise on the least-loaded live relay. Repeated requests for a room whose
  // answer is pending are merged.
  void RequestPlacement(const std::string& room, bool prefer_self);
  // Stores `room`'s latest snapshot (encoded, cluster/room_snapshot.h). Writes are batched on
  // the thread; a newer snapshot of a room replaces one not yet written.
  void SaveSnapshot(const std::string& room, std::vector<uint8_t> bytes);
  // The rooms this relay serves now. When one of their owner keys names a relay that is not
  // live (or an unusable value), this relay takes the lease back at its next refresh; other
  // relays claim such a room only after it stayed ownerless over two refreshes, so a live
  // holder always wins against a corrupted key and keeps its live copy.
  void SetLocalRooms(std::set<std::string> rooms);
  // This relay no longer holds `room` (closed): its ownership and snapshot are deleted if this
  // relay still owns it.
  void Release(const std::string& room);
  // Results since the last call (placements, claims), in order.
  std::vector<DirectoryEvent> TakeEvents();
  // The latest view; never null.
  std::shared_ptr<const DirectoryView> view() const;
  const DirectoryCounters& counters() const { return counters_; }

 private:
  explicit Directory(const DirectoryOptions& options);
  void Run();
  void Heartbeat();
  void Refresh();
  void ClaimOrphans(DirectoryView* view);
  void DoPlacement(const std::string& room, bool prefer_self);
  void FlushSnapshots();
  void DoRelease(const std::string& room);
  void Post(DirectoryEvent event);
  std::string Key(const char* kind, const std::string& name) const;

  DirectoryOptions options_;
  std::unique_ptr<RedisClient> redis_;  // the thread's only
  DirectoryCounters counters_;

  mutable std::mutex mu_;
  std::condition_variable wake_;
  bool stop_ = false;
  uint32_t users_ = 0, rooms_ = 0;
  bool draining_ = false;
  std::map<std::string, bool> placement_requests_;  // room -> prefer_self
  std::set<std::string> placement_pending_;          // requested, not yet answered
  std::map<std::string, std::vector<uint8_t>> snapshots_;
  std::vector<std::string> releases_;
  std::vector<DirectoryEvent> events_;
  std::shared_ptr<const DirectoryView> view_;
  std::set<std::string> local_rooms_;
  double last_ok_refresh_ = -1e9;  // thread only
  std::map<std::string, int> orphan_refreshes_;  // thread only: room -> refreshes seen ownerless

  std::thread thread_;
};

}  // namespace edgephys::cluster
