#include "loadgen/softbody_scene.h"

#include <algorithm>
#include <cmath>

#include "loadgen/loopback_room.h"
#include "loadgen/scenes/scenes.h"
#include "protocol/container_builder.h"

namespace edgephys::loadgen {
namespace {

constexpr uint32_t F(schema::EntityFlags f) { return static_cast<uint32_t>(f); }

std::vector<Vec3f> Nodes(const SoftBodySpec& s) {
  std::vector<Vec3f> out;
  for (size_t i = 0; i + 2 < s.particles.size(); i += 3) {
    out.push_back({s.particles[i], s.particles[i + 1], s.particles[i + 2]});
  }
  return out;
}

}  // namespace

void SoftBodyScene::Calibrate(size_t i, const std::vector<Vec3f>& nodes) {
  if (nodes.empty()) return;
  Vec3f c{};
  for (const Vec3f& p : nodes) c = {c.x + p.x, c.y + p.y, c.z + p.z};
  const float k = 1.0f / static_cast<float>(nodes.size());
  c = {c.x * k, c.y * k, c.z * k};
  float top = -1e9f, bottom = 1e9f;
  for (const Vec3f& p : nodes) {
    if (std::fabs(p.x - c.x) < 0.08f && std::fabs(p.z - c.z) < 0.08f) {
      top = std::max(top, p.y);
      bottom = std::min(bottom, p.y);
    }
  }
  if (top < bottom) top = bottom = c.y;
  hand_x[i] = c.x;
  hand_z[i] = c.z;
  hand_high[i] = top + kHandRadius + 0.1f;
  hand_low[i] = bottom + 0.6f * (top - bottom) + kHandRadius;
}

double SoftBodyScene::Deformation(size_t i, const std::vector<Vec3f>& nodes) const {
  double worst = 0;
  const auto& sp = springs[i];
  for (size_t s = 0; s + 1 < sp.size(); s += 2) {
    if (sp[s] >= nodes.size() || sp[s + 1] >= nodes.size()) continue;
    worst = std::max(worst, std::fabs(Dist(nodes[sp[s]], nodes[sp[s + 1]]) - rest_lengths[i][s / 2]));
  }
  return worst;
}

void SoftBodyScene::HandPose(size_t i, double t, Vec3f* pos) const {
  if (t < 0) {
    *pos = {hand_x[i], hand_high[i], hand_z[i]};
    return;
  }
  const double phase = static_cast<double>(i) / static_cast<double>(hand_x.size());
  const double u = std::fmod(t / period + phase, 1.0);
  const double f = 0.5 * (1.0 - std::cos(2.0 * M_PI * u));
  *pos = {hand_x[i], static_cast<float>(hand_high[i] - (hand_high[i] - hand_low[i]) * f), hand_z[i]};
}

void SoftBodyScene::PublishHands(Client& host, const std::vector<uint32_t>& hand_ids, double t) const {
  for (size_t i = 0; i < hand_ids.size(); ++i) {
    Vec3f pos;
    HandPose(i, t, &pos);
    (void)host.PublishTransform(hand_ids[i], pos, Quatf{});
  }
}

SoftBodyScene MakeSoftBodyScene(const SoftBodyOptions& o, uint32_t n) {
  SoftBodyScene s;
  s.period = o.poke_period_s;
  const float spacing = 1.2f;
  s.specs.push_back(StaticBox(kFloorId, {0, -0.1f, 0}, {0.5f * spacing * n + 1.0f, 0.1f, 1.5f}));
  s.specs.back().colliders[0].shape = schema::ColliderShape::Box;
  for (uint32_t i = 0; i < n; ++i) {
    physics::BunnyParams bp;
    bp.center = {(static_cast<float>(i) - 0.5f * static_cast<float>(n - 1)) * spacing, 0.6f, 0.0f};
    bp.target_particles = o.particles;
    EntitySpec bunny;
    bunny.id = kFirstBunnyId + i;
    bunny.name = "bunny";
    bunny.soft_body = physics::MakeBunnySoftBody(bp);
    const std::vector<Vec3f> nodes = Nodes(*bunny.soft_body);
    s.particles += static_cast<uint32_t>(nodes.size());
    s.springs.push_back(bunny.soft_body->springs);
    std::vector<float> rest;
    for (size_t k = 0; k + 1 < s.springs.back().size(); k += 2) {
      rest.push_back(static_cast<float>(Dist(nodes[s.springs.back()[k]], nodes[s.springs.back()[k + 1]])));
    }
    s.rest_lengths.push_back(std::move(rest));
    // Poke at the centroid: from above the body's top there down to ~55% of its height.
    Vec3f c{};
    float min_y = 1e9f;
    for (const Vec3f& p : nodes) {
      c = {c.x + p.x, c.y + p.y, c.z + p.z};
      min_y = std::min(min_y, p.y);
    }
    c = {c.x / nodes.size(), c.y / nodes.size(), c.z / nodes.size()};
    float top = min_y;
    for (const Vec3f& p : nodes) {
      if (std::fabs(p.x - c.x) < 0.08f && std::fabs(p.z - c.z) < 0.08f) top = std::max(top, p.y);
    }
    const float height = top - min_y;  // landed: bottom ~ floor (y 0)
    s.hand_x.push_back(c.x);
    s.hand_z.push_back(c.z);
    s.hand_high.push_back(height + kHandRadius + 0.15f);
    s.hand_low.push_back(0.55f * height);
    s.specs.push_back(std::move(bunny));
  }
  for (uint32_t i = 0; i < n; ++i) {
    EntitySpec hand;
    hand.id = kFirstHandId + i;
    hand.name = "hand";
    hand.flags = F(schema::EntityFlags::Hand) | F(schema::EntityFlags::Kinematic);
    hand.rigid_body = RigidBodySpec{};
    hand.rigid_body->mass = 0;
    hand.rigid_body->kinematic = true;
    hand.colliders.push_back(SphereCollider(kHandRadius));
    s.HandPose(i, -1.0, &hand.position);
    s.specs.push_back(std::move(hand));
  }
  return s;
}

}  // namespace edgephys::loadgen
