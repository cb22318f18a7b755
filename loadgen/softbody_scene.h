// The softbody scenario's scene (loadgen/softbody.h): a floor, N bunny soft bodies in a row and
// one kinematic sphere hand above each, and how the hands poke. Shared by the in-process run
// (softbody.cc) and the external-relay run (softbody_external.cc).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "client/client.h"
#include "loadgen/softbody.h"
#include "protocol/entity_spec.h"
#include "protocol/types.h"

namespace edgephys::loadgen {

// SoftBodyScene-local ids (the spawning client maps them to its entity ids).
inline constexpr uint32_t kFloorId = 1, kFirstBunnyId = 10, kFirstHandId = 100;
inline constexpr float kHandRadius = 0.08f;

// Floor, N bunnies in a row, one hand above each.
struct SoftBodyScene {
  std::vector<EntitySpec> specs;   // floor, bunnies, hands
  std::vector<std::vector<uint32_t>> springs;     // per bunny: index pairs
  std::vector<std::vector<float>> rest_lengths;   // per bunny, per spring
  std::vector<float> hand_x, hand_z, hand_high, hand_low;
  uint32_t particles = 0;
  double period = 1.5;

  // Aims hand i at bunny i as it lies now (`nodes`: its particles): above its centroid,
  // poking down to 40% of the body's thickness there. Nothing for empty `nodes`.
  void Calibrate(size_t i, const std::vector<Vec3f>& nodes);
  // Largest change of a spring's length from rest (m): deformation, whatever the pose.
  double Deformation(size_t i, const std::vector<Vec3f>& nodes) const;
  // t < 0: the hand waits above the bunny (settling); from t = 0 it pokes every period.
  void HandPose(size_t i, double t, Vec3f* pos) const;
  // Publishes every hand's pose at PhyS time `t` (HandPose) for `host`, hand i as hand_ids[i].
  void PublishHands(Client& host, const std::vector<uint32_t>& hand_ids, double t) const;
};

// The scene for `bunnies` bunnies of about options.particles particles each.
SoftBodyScene MakeSoftBodyScene(const SoftBodyOptions& options, uint32_t bunnies);

}  // namespace edgephys::loadgen
