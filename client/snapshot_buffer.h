// Client-side jitter buffer for one remote entity's received states. It keeps the most recent
// snapshots in sender-time order, estimates the offset between the local clock and the
// sender's clock, and runs an adaptive playout clock: the render time trails the estimated
// sender "now" by a delay that follows the observed send interval and arrival jitter.
// client/interpolation.h samples a pose from the buffer at that render time.
//
// Usage (one buffer per remote entity; `now` is the local monotonic clock in seconds):
//
//   edgephys::SnapshotBuffer buffer;
//   // on every received state (sender time converted from the wrapping u32 ms by the caller):
//   buffer.Insert({.sender_time_s = t, .position = p, .rotation = q}, now);
//   // every rendered frame:
//   double render_time = buffer.RenderTime(now);
//   edgephys::Pose pose = edgephys::Sample(buffer, render_time, Interpolator::kDualQuatSclerp);
//
// Units: all times are seconds (double). Sender times are in the sender's clock; receive times
// and `local_now_s` in the local clock. Positions metres, velocities m/s, angular velocities
// rad/s in the room (world) frame.
//
// Clock model: receive_time = sender_time + offset + queueing_delay, queueing_delay >= 0. The
// offset (base one-way latency plus the clock difference) is estimated as the minimum of
// (receive_time - sender_time) over a sliding window (two buckets of `offset_window_s` each), so
// it follows clock drift and route changes within at most two windows.
//
// Playout: target_delay = clamp(k * send_interval + jitter_p95, min_delay_s, max_delay_s), where
// send_interval is the median of recent sender-time gaps between consecutive snapshots (robust
// to loss) and jitter_p95 the 95th percentile of the recent queueing delays. RenderTime() moves
// towards (estimated sender now - target_delay) by speeding up or slowing down playback by at most
// `max_slew` (default 10%), so the render time never decreases and never jumps backwards; it
// jumps forwards only when more than `resync_threshold_s` behind (e.g. after a long stall).
//
// Sender time must be monotonic for the buffer's lifetime (unwrap the protocol's u32 ms before
// inserting); if the sender restarts its clock, call Clear().
//
// Thread-safety: none; use from one thread (typically the render thread, fed by Client updates).
// Memory: fixed at construction (capacity snapshots plus small fixed windows); Insert() and the
// accessors never allocate.
// Cost: Insert() is O(1) for in-order arrivals (O(capacity) worst case for a late one). The
// estimates are kept incrementally: each window (kJitterWindow raw delays, kIntervalWindow gaps)
// is also held sorted, and an arrival replaces the value it evicts with one binary search and a
// move of only the entries between the old and the new value, so the median and the percentile
// are read, not recomputed (exactly the values a full sort of the windows would give). The
// Client receive path calls Insert() once per remote entity state, so this is the hot path of a
// client rendering many entities (bench/interpolation_bench.cc: BM_Insert*). RenderTime() O(1);
// operator[] O(1); UpperBound() O(log capacity).
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "protocol/state_codec.h"

namespace edgephys {

// One received state of one entity.
struct Snapshot {
  double sender_time_s = 0;  // sender clock, seconds
  Vec3f position;            // metres, room frame
  Quatf rotation;            // unit quaternion (normalised on insert)
  bool has_linear_velocity = false;
  Vec3f linear_velocity;  // m/s, room frame; meaningful if has_linear_velocity
  bool has_angular_velocity = false;
  Vec3f angular_velocity;  // rad/s, room frame; meaningful if has_angular_velocity
};

struct SnapshotBufferConfig {
  size_t capacity = 32;                       // snapshots kept (>= 2)
  double initial_send_interval_s = 1.0 / 30;  // used until two snapshots have arrived
  double interval_multiplier = 1.5;           // k in the delay formula
  double min_delay_s = 0.010;
  double max_delay_s = 0.300;
  double offset_window_s = 4.0;       // one bucket of the min-filter (local seconds)
  double max_slew = 0.1;              // playout rate stays in [1 - max_slew, 1 + max_slew]
  double resync_threshold_s = 1.0;    // render time further behind than this jumps forward
  double duplicate_epsilon_s = 1e-6;  // sender times closer than this are the same snapshot
};

enum class InsertResult {
  kInserted,   // stored (possibly evicting the oldest)
  kDuplicate,  // a snapshot with the same sender time is already stored; ignored
  kTooOld,     // buffer full and older than everything kept; ignored (still counts for jitter)
  kInvalid,    // non-finite field or zero-length rotation; ignored
};

class SnapshotBuffer {
 public:
  static constexpr size_t kJitterWindow = 64;    // arrivals the jitter percentile looks at
  static constexpr size_t kIntervalWindow = 15;  // gaps the send-interval median looks at

  explicit SnapshotBuffer(const SnapshotBufferConfig& config = {});

  // Adds a snapshot received at local time `receive_time_s`, keeping time order (late arrivals
  // are inserted in place, not appended). Updates the clock offset, the send interval and the
  // jitter estimate.
  InsertResult Insert(const Snapshot& snapshot, double receive_time_s);

  // Drops every snapshot and all estimates (e.g. on a sender clock reset or a teleport).
  void Clear();

  // Takes every field of `config` but `capacity` (the ring keeps its size) and keeps the
  // snapshots, the clock offset and the send-interval and jitter estimates. The target delay is
  // recomputed at once; the playout clock then slews towards it at most `max_slew` (or jumps, past
  // `resync_threshold_s`), as after any change of the estimates. O(1).
  void Reconfigure(const SnapshotBufferConfig& config);
  const SnapshotBufferConfig& config() const { return config_; }

  size_t size() const { return count_; }
  bool empty() const { return count_ == 0; }
  size_t capacity() const { return capacity_; }
  // i-th snapshot in sender-time order, 0 = oldest. Requires i < size().
  const Snapshot& operator[](size_t i) const { return ring_[Slot(i)]; }
  const Snapshot& oldest() const { return (*this)[0]; }
  const Snapshot& newest() const { return (*this)[count_ - 1]; }
  // Index of the first snapshot whose sender time is > t (size() if none). O(log n).
  size_t UpperBound(double sender_time_s) const;

  // Estimated (receive_time - sender_time) minimum: base latency plus clock difference, seconds.
  // 0 before the first snapshot.
  double clock_offset_s() const;
  // Sender clock reading estimated for local time `local_time_s` (= local - offset).
  double EstimateSenderTime(double local_time_s) const { return local_time_s - clock_offset_s(); }
  // Median recent gap between consecutive snapshots' sender times, seconds.
  double send_interval_s() const { return send_interval_s_; }
  // 95th percentile of recent queueing delays (receive - sender - offset), seconds, >= 0.
  double jitter_p95_s() const { return jitter_p95_s_; }
  // The delay the playout clock converges to, seconds.
  double target_delay_s() const { return target_delay_s_; }

  // Render time (sender clock) for a frame at local time `local_now_s`. Stateful: call once per
  // frame with non-decreasing `local_now_s`; the result never decreases. Before the first
  // snapshot it returns 0 (and the playout clock starts at the first call after one arrived).
  double RenderTime(double local_now_s);
  // Current delay of the playout clock behind the estimated sender time, seconds (valid after
  // RenderTime() has been called).
  double current_delay_s() const { return current_delay_s_; }

 private:
  // Ring index of the i-th snapshot; i < 2 * capacity_ - head_ (no division: this is on every
  // access).
  size_t Slot(size_t i) const {
    const size_t j = head_ + i;
    return j < capacity_ ? j : j - capacity_;
  }
  void UpdateOffset(double raw_offset_s, double receive_time_s);
  // Recomputes jitter_p95_s_ and target_delay_s_ from the sorted windows: O(1).
  void UpdateEstimates();

  SnapshotBufferConfig config_;
  std::vector<Snapshot> ring_;  // fixed size = capacity
  size_t capacity_ = 0;         // ring_.size()
  size_t head_ = 0;             // index of the oldest
  size_t count_ = 0;

  // Clock offset min-filter: two buckets of offset_window_s local seconds.
  bool has_offset_ = false;
  double bucket_start_s_ = 0;
  double bucket_min_s_ = 0;
  double previous_bucket_min_s_ = 0;

  // Raw (receive - sender) of the last kJitterWindow arrivals, in arrival order (a ring, to know
  // which value leaves the window) and sorted ascending (first raw_offsets_count_ entries).
  std::array<double, kJitterWindow> raw_offsets_{};
  std::array<double, kJitterWindow> raw_offsets_sorted_{};
  size_t raw_offsets_count_ = 0;
  size_t raw_offsets_next_ = 0;

  // Sender-time gaps between consecutive newest snapshots: ring and sorted, as above.
  std::array<double, kIntervalWindow> gaps_{};
  std::array<double, kIntervalWindow> gaps_sorted_{};
  size_t gaps_count_ = 0;
  size_t gaps_next_ = 0;

  double send_interval_s_ = 0;
  double jitter_p95_s_ = 0;
  double target_delay_s_ = 0;

  // Playout clock.
  bool playout_started_ = false;
  double last_local_now_s_ = 0;
  double render_time_s_ = 0;
  double current_delay_s_ = 0;
};

}  // namespace edgephys
