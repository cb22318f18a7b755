#include "loadgen/pose_history.h"

namespace edgephys::loadgen {

void PoseHistory::Add(const Publish& p) {
  if (count_ > 0) {
    const Vec3f& last = ring_[(count_ - 1) % kCapacity].position;
    if (last.x == p.position.x && last.y == p.position.y && last.z == p.position.z) return;
  }
  ring_[count_ % kCapacity] = p;
  ++count_;
}

const PoseHistory::Publish* PoseHistory::Match(const Vec3f& received) const {
  for (size_t back = 1; back <= size(); ++back) {
    const Publish& sent = ring_[(count_ - back) % kCapacity];
    const float dx = sent.position.x - received.x;
    const float dy = sent.position.y - received.y;
    const float dz = sent.position.z - received.z;
    if (dx * dx + dy * dy + dz * dz < kMatchDistanceSq) return &sent;
  }
  return nullptr;
}

}  // namespace edgephys::loadgen
