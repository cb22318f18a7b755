#include "physics_backend/state_hash.h"

#include <cstring>
#include <vector>

#include "physics_backend/physics_world.h"

namespace edgephys::physics {
namespace {

uint64_t HashFloat(float f, uint64_t hash) {
  uint32_t bits;
  std::memcpy(&bits, &f, sizeof(bits));
  return Fnv1a(&bits, sizeof(bits), hash);
}

uint64_t HashVec(const Vec3f& v, uint64_t hash) {
  hash = HashFloat(v.x, hash);
  hash = HashFloat(v.y, hash);
  return HashFloat(v.z, hash);
}

}  // namespace

uint64_t Fnv1a(const void* data, size_t size, uint64_t hash) {
  const auto* p = static_cast<const uint8_t*>(data);
  for (size_t i = 0; i < size; ++i) {
    hash ^= p[i];
    hash *= kFnv1aPrime;
  }
  return hash;
}

uint64_t HashWorldState(const PhysicsWorld& world) {
  std::vector<uint32_t> ids;
  world.EntityIds(&ids);
  std::vector<Vec3f> nodes;
  uint64_t hash = kFnv1aOffset;
  for (uint32_t id : ids) {
    EntityState s;
    Vec3f lin, ang;
    (void)world.GetState(id, &s);
    (void)world.GetVelocity(id, &lin, &ang);
    hash = Fnv1a(&id, sizeof(id), hash);
    hash = HashVec(s.position, hash);
    hash = HashFloat(s.rotation.x, hash);
    hash = HashFloat(s.rotation.y, hash);
    hash = HashFloat(s.rotation.z, hash);
    hash = HashFloat(s.rotation.w, hash);
    hash = HashVec(lin, hash);
    hash = HashVec(ang, hash);
    if (world.GetSoftBodyNodes(id, &nodes).ok()) {
      for (const Vec3f& n : nodes) hash = HashVec(n, hash);
    }
  }
  return hash;
}

}  // namespace edgephys::physics
