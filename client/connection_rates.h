// Per-connection throughput over a sliding window: bytes and packets per second sent and
// received, from the cumulative counters of ConnectionStats (protocol/connection_types.h).
//
// The client SDK's real-time connection status (the C API's edgephys_client_get_connection_status)
// samples one of these on every update. The class has no clock and does no I/O: the caller
// passes the time of each sample, so tests drive it with any timeline.
//
// Cost: Sample() is O(1) and allocates nothing (a fixed ring of kSlots samples, ~0.5 KB).
// Thread-safety: none; one owner.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace edgephys {

struct ConnectionStats;

class ConnectionRates {
 public:
  // Cumulative counters at one instant (monotonic while one connection lasts).
  struct Totals {
    uint64_t bytes_sent = 0;
    uint64_t bytes_received = 0;
    uint64_t packets_sent = 0;
    uint64_t packets_received = 0;
  };
  static Totals From(const ConnectionStats& stats);

  // Per-second rates over the window (0 until two samples at least 1 ms apart exist).
  struct Rates {
    double send_bytes_per_s = 0;
    double receive_bytes_per_s = 0;
    double send_packets_per_s = 0;
    double receive_packets_per_s = 0;
  };

  // `window_s` (> 0): how far back the rates look. Samples are kept every window_s / (kSlots - 1)
  // seconds at most; between those, the newest sample is replaced.
  explicit ConnectionRates(double window_s = 1.0);

  // Records the counters at `now_s` (seconds, any monotonic clock). A time earlier than the last
  // sample, or counters lower than the last sample's (a new connection), start the window again
  // from this sample. A non-finite time is ignored.
  void Sample(double now_s, const Totals& totals);

  // Means from a base sample to the newest one. The base is the oldest kept sample at most
  // window_s older than the newest, so the span is between window_s / 2 and window_s once that
  // much has been sampled. If that span would be shorter than window_s / 2 (sampling paused for
  // longer than the window, e.g. a stalled game loop), the base is the last sample before it:
  // the mean then covers the pause, until half a window has been sampled again.
  Rates Get() const;

  // Forgets every sample.
  void Reset();

  static constexpr size_t kSlots = 11;

 private:
  struct Point {
    double t = 0;
    Totals totals;
  };
  const Point& At(size_t i) const { return ring_[(head_ + i) % kSlots]; }  // 0 = oldest

  double window_s_;
  double spacing_s_;
  std::array<Point, kSlots> ring_{};  // kept samples, oldest at head_
  size_t head_ = 0;
  size_t count_ = 0;
  Point newest_;        // the latest sample (also ring_'s last entry when it was just kept)
  bool have_newest_ = false;
};

}  // namespace edgephys
