#include "loadgen/motion.h"

#include <cmath>
#include <random>

#include "client/client.h"
#include "protocol/container_builder.h"

namespace edgephys::loadgen {

Motion::Motion(const MotionParams& p, uint32_t index) {
  std::mt19937_64 rng(p.seed * 1000003u + index);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  cx_ = (index % 16) * 3.0;
  cy_ = 1.5;
  cz_ = (index / 16) * 3.0;
  // Frequencies in a narrow band so the speed stays near the target everywhere on the path.
  wx_ = 1.0 + 0.2 * u(rng);
  wy_ = 0.7 + 0.2 * u(rng);
  wz_ = 1.3 + 0.2 * u(rng);
  // Amplitudes so that the RMS speed is speed_mps: v^2 ~ sum(a_i^2 w_i^2)/2.
  double norm = std::sqrt((wx_ * wx_ + 0.25 * wy_ * wy_ + wz_ * wz_) / 2.0);
  double a = p.speed_mps / norm;
  ax_ = a;
  ay_ = 0.5 * a;
  az_ = a;
  px_ = 6.283185307 * u(rng);
  py_ = 6.283185307 * u(rng);
  pz_ = 6.283185307 * u(rng);
  spin_rad_s_ = p.spin_dps * 3.14159265358979 / 180.0;
  axis_phase_ = 6.283185307 * u(rng);
  axis_rate_ = 0.2 + 0.1 * u(rng);  // rad/s: the axis turns slowly
}


EntityState Motion::At(double t) const {
  EntityState s;
  s.position = {static_cast<float>(cx_ + ax_ * std::sin(wx_ * t + px_)),
                static_cast<float>(cy_ + ay_ * std::sin(wy_ * t + py_)),
                static_cast<float>(cz_ + az_ * std::sin(wz_ * t + pz_))};
  double th = axis_phase_ + axis_rate_ * t;
  double ux = std::cos(th) * 0.6, uy = 0.8, uz = std::sin(th) * 0.6;  // unit length
  double half = 0.5 * spin_rad_s_ * t;
  double sh = std::sin(half);
  s.rotation = {static_cast<float>(ux * sh), static_cast<float>(uy * sh),
                static_cast<float>(uz * sh), static_cast<float>(std::cos(half))};
  return s;
}

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
