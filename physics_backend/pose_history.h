// PoseHistory: the recent poses of one moving thing (a user's hand) with the times they hold,
// and the velocity they show, for releasing a held object at the hand's velocity.
//
// Why: a grabbed object follows its hand by a velocity drive that removes the whole pose error
// in one physics step (PhysicsConfig::grab_gain). Hand poses reach PhyS from the network at
// about the physics rate but not in step with it, so a step sees no new pose (the drive asks
// for 0) or two (it asks for twice the hand's speed). The drive's last step is therefore no
// estimate of how fast the hand moved: a released object left with 0 to ~2.4x the hand's speed.
// The poses' own times are: a least-squares line through the poses of the last window is the
// hand's mean velocity over it, however the poses fell between steps.
//
// Units: seconds (any clock, as long as one history uses one), metres, radians per second.
// Thread-safety: none (one owner). Cost: Add O(1); Estimate O(kCapacity). 8 poses, ~300 bytes.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "protocol/types.h"

namespace edgephys::physics {

class PoseHistory {
 public:
  static constexpr size_t kCapacity = 8;

  // Records a pose held at `time`. A pose at the time of the newest replaces it (a later update
  // for the same instant); a pose older than the newest is ignored (reordered input). Poses with
  // a non-finite time are ignored.
  void Add(double time, const Vec3f& position, const Quatf& rotation);
  void Clear() { count_ = 0; }
  size_t size() const { return count_; }

  // The linear and angular velocity the poses of the last `window_s` seconds (up to the newest)
  // show: least-squares slopes of position, and of the rotation vector relative to the newest
  // rotation, against time. False (outputs untouched) with fewer than 3 poses in the window or
  // when they span less than a third of it: too little to tell a velocity from jitter.
  bool Estimate(double window_s, Vec3f* linear, Vec3f* angular) const;

  // The newest pose; false if none.
  bool Newest(double* time, Vec3f* position, Quatf* rotation) const;

 private:
  struct Sample {
    double t = 0;
    Vec3f p;
    Quatf q;
  };
  const Sample& At(size_t back) const {  // 0 = newest
    return ring_[(next_ + kCapacity - 1 - back) % kCapacity];
  }
  std::array<Sample, kCapacity> ring_{};
  size_t next_ = 0;
  size_t count_ = 0;
};

}  // namespace edgephys::physics
