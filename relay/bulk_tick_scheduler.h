// BulkTickScheduler: when a bulk room (more than Relay::kBulkRoomEntities entities, e.g. a PhyS
// scene of thousands of bodies) ticks relative to the light rooms (hand poses) on one relay.
//
// A bulk room's tick (frame, picks, encoding for each receiver) takes milliseconds of the relay's
// loop. Relay::TickDueRooms already runs it after the light rooms due in the same update. But a
// bulk room that falls due just *before* a light room would start its pass then and hold the
// light room's tick until it finishes: with two rooms at the same tick rate that happens every
// tick or never, depending on the phase between them. So a due bulk room waits for a light room
// whose tick is due within lead() (1.5 times the bulk pass's recent duration, at least
// kMinLeadS), and then ticks right after it in that update, as long as that keeps it at most half
// of its own tick interval late. Its tick schedule keeps its phase (Room: next tick = last due
// time + interval), so after one wait a bulk room at the light rooms' rate follows them every tick
// and its rate is unchanged.
//
// Not thread-safe: the relay's loop thread only. Times in seconds on the relay's clock (Update's
// `now`); pass durations in seconds on a steady clock.
#pragma once

#include <algorithm>
#include <cmath>

namespace edgephys {

class BulkTickScheduler {
 public:
  static constexpr double kMinLeadS = 0.002;
  static constexpr double kMaxLateFraction = 0.5;  // of the bulk room's tick interval

  // Whether a bulk room due since `bulk_due` (<= now), ticking every `bulk_interval_s`, should
  // wait for the next light room's tick at `next_light_tick` (> now; +infinity: no light room).
  bool ShouldWait(double now, double bulk_due, double bulk_interval_s, double next_light_tick) const {
    if (!(next_light_tick > now) || !std::isfinite(next_light_tick)) return false;
    if (next_light_tick - now >= lead()) return false;  // done before the light room is due
    return next_light_tick - bulk_due <= kMaxLateFraction * bulk_interval_s;
  }

  // The wall time of a bulk pass (all bulk rooms ticked in one update), for lead().
  void RecordPass(double seconds) {
    if (!std::isfinite(seconds) || seconds < 0) return;
    pass_s_ = pass_s_ <= 0 ? seconds : 0.8 * pass_s_ + 0.2 * seconds;
  }

  double lead() const { return std::max(kMinLeadS, 1.5 * pass_s_); }

 private:
  double pass_s_ = 0;  // smoothed bulk pass duration
};

}  // namespace edgephys
