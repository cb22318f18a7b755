#include "loadgen/avatar.h"

#include <cmath>

#include "protocol/container_builder.h"

namespace edgephys::loadgen {
namespace {

uint32_t Flag(schema::EntityFlags f) { return static_cast<uint32_t>(f); }

SpawnDesc Kinematic(const Vec3f& position, uint32_t flags) {
  SpawnDesc d{.position = position, .flags = flags};
  d.rigid_body = RigidBodySpec{};
  d.rigid_body->kinematic = true;
  d.rigid_body->mass = 0;
  return d;
}

}  // namespace

Vec3f AvatarHandPosition(const Vec3f& home, uint32_t index, double t, float side) {
  const double w = 1.3 + 0.01 * (index % 17);
  return {static_cast<float>(home.x + side * 0.25 + 0.2 * std::sin(w * t + index)),
          static_cast<float>(1.1 + 0.15 * std::sin(0.9 * w * t + 2 * index)),
          static_cast<float>(home.z + 0.2 * std::cos(w * t + index))};
}

bool SpawnAvatar(Client& client, const Vec3f& home, uint32_t index, double now, AvatarIds* ids) {
  auto head = client.Spawn(Kinematic({home.x, 1.6f, home.z}, Flag(schema::EntityFlags::Avatar)));
  if (!head.ok()) return false;
  ids->head = *head;
  for (uint32_t* hand : {&ids->left, &ids->right}) {
    const float side = hand == &ids->left ? -1.f : 1.f;
    SpawnDesc d = Kinematic(AvatarHandPosition(home, index, now, side),
                            Flag(schema::EntityFlags::Hand));
    ColliderSpec trigger = SphereCollider(0.15f);
    trigger.is_trigger = true;
    d.colliders.push_back(trigger);
    auto id = client.Spawn(d);
    if (!id.ok()) return false;
    *hand = *id;
  }
  return true;
}

}  // namespace edgephys::loadgen
