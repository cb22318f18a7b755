// The impairment model of udp_impair (tests/netem/udp_impair.cc): what happens to each datagram
// of one direction, and a bounded queue that releases the surviving copies when they are due.
// Header-only, no I/O, so tests/netem/impair_schedule_test.cc can measure it.
//
// Semantics follow tc netem with "loss L delay D J duplicate P reorder R" (iproute2 sets gap 1
// when reorder is given, and netem without a distribution table draws the jitter uniformly):
//   - with probability `loss` the datagram is dropped;
//   - otherwise it yields one copy, and with probability `duplicate` a second one;
//   - each copy independently: with probability `reorder` it is sent at once (delay 0, so it
//     overtakes the copies still waiting), else after delay_s + U(-jitter_s, +jitter_s),
//     never below 0. Because the queue releases copies in order of due time, jitter reorders
//     as it does in netem's time-sorted queue.
// So every copy that is not reordered leaves within [delay_s - jitter_s, delay_s + jitter_s]
// (clamped at 0) of its arrival. Draws are deterministic for a seed (std::mt19937_64, 53-bit
// uniforms) and a fixed number of draws is made per datagram and per copy.
//
// Thread-safety: none. Cost: O(1) per Decide(), O(log queued) per Push/Pop; the queue holds at
// most max_items datagrams and max_bytes payload bytes (a Push beyond either is refused).
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <random>
#include <span>
#include <vector>

#include "protocol/datagram_delay_queue.h"

namespace edgephys::netem {

struct ImpairParams {
  double loss = 0;       // probability a datagram is dropped
  double duplicate = 0;  // probability a surviving datagram is delivered twice
  double reorder = 0;    // probability a copy skips the delay (sent at once)
  double delay_s = 0;    // base one-way delay
  double jitter_s = 0;   // uniform +- around delay_s
};

struct Fate {
  int copies = 0;             // 0 (lost), 1, or 2 (duplicated)
  double delay_s[2] = {0, 0};  // per copy
  bool reordered[2] = {false, false};
};

class ImpairSchedule {
 public:
  ImpairSchedule(const ImpairParams& params, uint64_t seed) : params_(params), rng_(seed) {}

  Fate Decide() {
    Fate fate;
    const bool lost = Uniform() < params_.loss;
    const bool duplicated = Uniform() < params_.duplicate;
    for (int i = 0; i < 2; ++i) {  // always draw for both copies: a fixed stream per datagram
      const double jitter = (2 * Uniform() - 1) * params_.jitter_s;
      const bool reordered = Uniform() < params_.reorder;
      fate.reordered[i] = reordered;
      fate.delay_s[i] = reordered ? 0.0 : std::max(0.0, params_.delay_s + jitter);
    }
    fate.copies = lost ? 0 : (duplicated ? 2 : 1);
    return fate;
  }

  const ImpairParams& params() const { return params_; }

 private:
  double Uniform() { return static_cast<double>(rng_() >> 11) * 0x1.0p-53; }  // [0, 1)

  ImpairParams params_;
  std::mt19937_64 rng_;
};

// The queue of datagrams waiting until their copies are due, tagged with the caller's routing
// key (udp_impair: client slot and generation).
using DelayQueue = edgephys::DatagramDelayQueue<uint64_t>;

}  // namespace edgephys::netem
