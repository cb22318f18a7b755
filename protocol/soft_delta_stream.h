// Format 11 soft-body streams (protocol/soft_delta_codec.h, docs/protocol.md §5f): which
// versions a receiver holds, and what each side keeps to code against them.
//
// SoftDeltaSender (relay, one per receiver): per soft body, the lattice coordinates of the last
// kSoftHistory versions it sent this receiver, with, per version, which particles the receiver
// acknowledged (per packet: OnSent / OnAcked). A record references the newest FULLY
// acknowledged version as its baseline (and the next older one for extrapolation), else it is
// a keyframe. A new version whose particles are all within `threshold_m` of the newest
// acknowledged one is not sent at all (settled): a body at rest costs nothing. The newest
// version is re-sent whole when not fully acknowledged after `resend_after_s` and nothing newer
// came; a newer version simply supersedes it (deltas are against acknowledged versions, so a
// lost packet costs nothing but its own update).
//
// SoftDeltaReceiver (client): per body, the kSoftHistory highest versions it decoded (which
// particles of each), and what to display: per particle, the newest version decoded.
// Why an acknowledged baseline is always held: the sender references only versions among the
// last kSoftHistory versions it sent, so fewer than kSoftHistory newer versions exist; the
// receiver keeps the kSoftHistory highest it decoded, so it never evicts one the sender may
// still reference, and an acknowledgement means the packet was delivered (connection.h). A
// record whose baseline is not held (forged, or evicted by a forged newer version) is dropped
// and counted (`unknown_baseline`); records older than every held version are dropped
// (`stale`). Nothing is ever decoded against a baseline the receiver does not hold.
//
// Memory: sender ~13 bytes per particle per version: kSoftHistory x 13 x particles per
// (receiver, body), ~106 KB for a 510-particle body. Receiver the same per body, all bodies
// together bounded by `max_held_particles` (versions x particles; over it a new body or
// version is dropped and counted).
// Thread-safety: none; one owner thread each. Cost: O(particles) per version prepared (once
// per version: quantise, threshold test) and per record coded or decoded.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <vector>

#include "protocol/soft_delta_codec.h"
#include "protocol/status.h"
#include "protocol/types.h"

namespace edgephys {

inline constexpr size_t kSoftHistory = 16;
// Sticky quantisation bound, in lattice steps: a particle keeps its baseline lattice point while
// the truth is within this (Euclidean) of it. Just under the nearest point's own worst case
// (sqrt(3)/2 = 0.866), so the error against what was sent stays within the lattice bound.
inline constexpr double kSoftStickyBound = 0.86;

struct SoftDeltaSenderConfig {
  float step_m = 0.001f;       // lattice step (the room's position step)
  float threshold_m = 0.001f;  // settled: every particle within this of the acknowledged version
};

struct SoftDeltaSenderStats {
  uint64_t records = 0;
  uint64_t keyframes = 0;      // records with predictor 0
  uint64_t extrapolated = 0;   // records with predictor 2
  uint64_t settled = 0;        // versions not sent: within the threshold of the acked one
  uint64_t resends = 0;        // versions re-sent (not fully acknowledged in time)
  uint64_t bytes = 0;          // record bytes
};

class SoftDeltaSender {
 public:
  explicit SoftDeltaSender(const SoftDeltaSenderConfig& config);

  // Whether body `id` must be sent now, its current particles being version `version`
  // (versions increase) at `time_ms`. On true the version is what AddRecords codes next.
  bool Prepare(uint32_t id, uint32_t version, std::span<const Vec3f> nodes, uint32_t time_ms,
               double now, double resend_after_s);

  // Payload building: Begin, AddRecords (any bodies, each after a true Prepare), Finish; then
  // OnSent with the packet's sequence, or OnNotSent.
  void BeginPayload(std::span<uint8_t> out, uint32_t time_ms);
  // Appends records for particles [*first, ...) of body `id`'s prepared version and advances
  // *first; false if not even one particle fit (finish and send the payload, begin another).
  bool AddRecords(uint32_t id, uint32_t* first);
  size_t FinishPayload();  // the payload's size; 0 if it holds no record
  bool empty() const { return pending_.empty(); }
  void OnSent(uint16_t sequence, double now);
  void OnNotSent();
  // True if `sequence` carried records of this stream (their particles count as received).
  bool OnAcked(uint16_t sequence);

  void Forget(uint32_t id);
  size_t tracked() const { return tracks_.size(); }
  const SoftDeltaSenderStats& stats() const { return stats_; }
  // Newest fully acknowledged version of `id` (0: none). For tests and diagnostics.
  uint32_t AckedVersion(uint32_t id) const;

 private:
  struct Version {
    uint32_t version = 0;  // 0: free slot
    uint32_t time_ms = 0;
    double sent_at = -1e9;
    uint32_t acked_count = 0;
    std::vector<int32_t> q;        // 3 x particles
    std::vector<uint8_t> acked;    // per particle
    bool full() const { return !acked.empty() && acked_count == acked.size(); }
  };
  struct Track {
    std::vector<Version> versions;  // kSoftHistory slots
    size_t newest = 0;              // slot of the newest version (if any)
    uint32_t settled_version = 0;
  };
  struct Entry {
    uint32_t id, version, first, count;
  };
  struct PacketRecord {
    bool valid = false;
    uint16_t sequence = 0;
    std::vector<Entry> entries;
  };
  const Version* NewestAcked(const Track& t, uint32_t below, size_t size, uint32_t before_ms,
                             bool need_older_time) const;

  SoftDeltaSenderConfig config_;
  std::unordered_map<uint32_t, Track> tracks_;
  std::vector<PacketRecord> records_;
  std::vector<Entry> pending_;
  std::vector<int32_t> sticky_;  // Prepare's copy of the baseline
  std::span<uint8_t> out_;
  size_t pos_ = 0;
  uint32_t time_ms_ = 0;
  SoftDeltaScratch scratch_;
  SoftDeltaSenderStats stats_;
};

struct SoftDeltaReceiverStats {
  uint64_t payloads = 0;
  uint64_t records = 0;            // decoded and stored
  uint64_t malformed = 0;          // payloads with a malformed record (the rest is dropped)
  uint64_t unknown_baseline = 0;   // records whose baseline(s) are not held: dropped
  uint64_t stale = 0;              // records older than every held version: dropped
  uint64_t over_capacity = 0;      // records dropped by the max_bodies / max_held_particles bounds
};

// A record that changed what is displayed: particles [first, first + count) of body `id`.
struct SoftDeltaUpdate {
  uint32_t id = 0;
  uint32_t first = 0;
  uint32_t count = 0;
};

class SoftDeltaReceiver {
 public:
  SoftDeltaReceiver(float step_m, uint32_t max_total, size_t max_bodies = 1024,
                    size_t max_held_particles = size_t{1} << 21);

  // Decodes a format-11 payload. Records are applied in order; a malformed record ends the
  // payload (kMalformed; the records before it stay applied). Records that cannot be decoded
  // against what is held are dropped and counted (Ok). updates() lists what changed.
  Status Decode(std::span<const uint8_t> payload);
  std::span<const SoftDeltaUpdate> updates() const { return updates_; }
  // Body `id`'s displayed particles (newest decoded version of each); empty if unknown.
  std::span<const Vec3f> Display(uint32_t id) const;
  // The versions of `id` held (for tests).
  std::vector<uint32_t> HeldVersions(uint32_t id) const;

  void Forget(uint32_t id);
  const SoftDeltaReceiverStats& stats() const { return stats_; }

 private:
  struct Held {
    uint32_t version = 0;  // 0: free
    uint32_t time_ms = 0;
    std::vector<int32_t> q;
    std::vector<uint8_t> have;
  };
  struct Body {
    uint32_t total = 0;
    std::vector<Held> held;         // kSoftHistory slots, allocated on first use
    std::vector<Vec3f> display;
    std::vector<uint32_t> shown;    // per particle: version displayed
  };
  const Held* Find(const Body& b, uint32_t version, uint32_t first, uint32_t count) const;
  Status Apply(const SoftDeltaRecord& r);
  void Release(Body& b);

  float step_m_;
  uint32_t max_total_;
  size_t max_bodies_;
  size_t max_held_particles_;
  size_t held_particles_ = 0;
  std::unordered_map<uint32_t, Body> bodies_;
  std::vector<SoftDeltaUpdate> updates_;
  std::vector<int32_t> scratch_;
  SoftDeltaReceiverStats stats_;
};

}  // namespace edgephys
