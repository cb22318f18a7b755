#include "loadgen/scenes/scenes.h"

#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>
#include <BulletSoftBody/btSoftRigidDynamicsWorld.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <unordered_map>

namespace edgephys::physics {
namespace {

Quatf AxisAngle(float ax, float ay, float az, float angle) {
  const float s = std::sin(angle * 0.5f);
  const float len = std::sqrt(ax * ax + ay * ay + az * az);
  return Quatf{ax / len * s, ay / len * s, az / len * s, std::cos(angle * 0.5f)};
}

btVector3 Bt(const Vec3f& v) { return btVector3(v.x, v.y, v.z); }
btQuaternion Bt(const Quatf& q) { return btQuaternion(q.x, q.y, q.z, q.w); }

}  // namespace

float MultiObjectHalfWidth(const MultiObjectParams& p) {
  const float box = 2.0f * p.box_half_extent;
  // `layers` layers at ~60% packing: (2W)^2 * layers * box * 0.6 = N * box^3.
  const float w = 0.5f * std::sqrt(static_cast<float>(p.num_objects) * box * box /
                                   (0.6f * std::max(0.1f, p.layers)));
  return std::max(w, 1.0f);
}

void StirrerPose(const MultiObjectParams& p, double time, Vec3f* position, Quatf* rotation) {
  *position = Vec3f{0.0f, p.stirrer_center_y, 0.0f};
  *rotation = AxisAngle(0, 1, 0, static_cast<float>(std::fmod(time * p.stirrer_angular_speed,
                                                              2.0 * M_PI)));
}

std::vector<EntitySpec> MultiObjectSpecs(const MultiObjectParams& p) {
  std::vector<EntitySpec> specs;
  const float w = MultiObjectHalfWidth(p);
  const float h = p.wall_height;
  const float t = 0.1f;  // wall half thickness
  specs.push_back(StaticBox(kSceneFloorId, {0, -t, 0}, {w + 2 * t, t, w + 2 * t}));
  specs.push_back(StaticBox(2, {w + t, h / 2, 0}, {t, h / 2, w + 2 * t}));
  specs.push_back(StaticBox(3, {-w - t, h / 2, 0}, {t, h / 2, w + 2 * t}));
  specs.push_back(StaticBox(4, {0, h / 2, w + t}, {w, h / 2, t}));
  specs.push_back(StaticBox(5, {0, h / 2, -w - t}, {w, h / 2, t}));
  for (EntitySpec& s : specs) s.colliders[0].shape = schema::ColliderShape::Box;

  EntitySpec stirrer;
  stirrer.id = kSceneStirrerId;
  StirrerPose(p, 0.0, &stirrer.position, &stirrer.rotation);
  stirrer.flags = static_cast<uint32_t>(schema::EntityFlags::Kinematic);
  stirrer.rigid_body = RigidBodySpec{};
  stirrer.rigid_body->mass = 0;
  stirrer.rigid_body->kinematic = true;
  stirrer.rigid_body->friction = p.friction;
  stirrer.colliders.push_back(BoxCollider({p.stirrer_reach * w, p.stirrer_half_height, 0.05f}));
  specs.push_back(stirrer);

  std::mt19937 rng(p.seed);
  std::uniform_real_distribution<float> jitter(-0.2f, 0.2f);
  std::uniform_real_distribution<float> angle(0.0f, 6.2831853f);
  const float cell = 5.0f * p.box_half_extent;
  const int per_row = std::max(1, static_cast<int>(2.0f * (w - cell) / cell));
  for (int i = 0; i < p.num_objects; ++i) {
    const int layer = i / (per_row * per_row);
    const int in_layer = i % (per_row * per_row);
    const float x = -w + cell + (in_layer % per_row) * cell + jitter(rng) * p.box_half_extent;
    const float z = -w + cell + (in_layer / per_row) * cell + jitter(rng) * p.box_half_extent;
    const float y = 1.2f + layer * cell;
    EntitySpec box = DynamicBox(kSceneFirstBoxId + static_cast<uint32_t>(i), {x, y, z},
                                {p.box_half_extent, p.box_half_extent, p.box_half_extent},
                                p.box_mass);
    box.rotation = AxisAngle(jitter(rng), 1.0f, jitter(rng), angle(rng));
    box.rigid_body->friction = p.friction;
    box.rigid_body->restitution = p.restitution;
    box.flags = static_cast<uint32_t>(schema::EntityFlags::Interactable);
    specs.push_back(box);
  }
  return specs;
}

// ---------------------------------------------------------------------------------------------

PhysSMultiObjectScene::PhysSMultiObjectScene(const MultiObjectParams& params)
    : params_(params), world_(params.config) {
  for (const EntitySpec& spec : MultiObjectSpecs(params_)) {
    const std::vector<uint8_t> buf = BuildContainer(spec);
    (void)world_.AddEntity(AsContainer(buf));
  }
  moved_.reserve(static_cast<size_t>(params_.num_objects) + 16);
  events_.reserve(1024);
}

void PhysSMultiObjectScene::Step() {
  ++steps_;
  Vec3f pos;
  Quatf rot;
  StirrerPose(params_, static_cast<double>(steps_) * params_.config.fixed_dt, &pos, &rot);
  (void)world_.MoveToTransform(kSceneStirrerId, pos, rot);
  world_.Step();
  world_.CollectStates(&moved_);
  events_.clear();
  world_.DrainEvents(&events_);
}

size_t PhysSMultiObjectScene::MovingBoxes(float min_speed) const {
  size_t n = 0;
  for (int i = 0; i < params_.num_objects; ++i) {
    const btRigidBody* b = world_.RigidBodyForTesting(kSceneFirstBoxId + static_cast<uint32_t>(i));
    if (b != nullptr && b->isActive() && b->getLinearVelocity().length() > min_speed) ++n;
  }
  return n;
}

// ---------------------------------------------------------------------------------------------

struct RawBulletMultiObjectScene::Impl {
  MultiObjectParams params;
  std::unique_ptr<btCollisionConfiguration> collision_config;
  std::unique_ptr<btCollisionDispatcher> dispatcher;
  std::unique_ptr<btBroadphaseInterface> broadphase;
  std::unique_ptr<btConstraintSolver> solver;
  std::unique_ptr<btDiscreteDynamicsWorld> world;
  std::vector<std::unique_ptr<btCollisionShape>> shapes;
  std::vector<std::unique_ptr<btDefaultMotionState>> motion_states;
  std::vector<std::unique_ptr<btRigidBody>> bodies;
  std::vector<btRigidBody*> boxes;
  btRigidBody* stirrer = nullptr;
  uint64_t steps = 0;
};

RawBulletMultiObjectScene::RawBulletMultiObjectScene(const MultiObjectParams& params)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.params = params;
  // Bullet as its examples set it up, every setting at its default: btDefaultCollisionConfiguration,
  // btDbvtBroadphase, btSequentialImpulseConstraintSolver (10 iterations, split impulse, warm
  // starting), btDiscreteDynamicsWorld, sleeping at 0.8 m/s / 1.0 rad/s after 2 s, no CCD,
  // motion states on every body. Only the scene (shapes, masses, friction, restitution, gravity,
  // the step length) comes from `params`.
  m.collision_config = std::make_unique<btDefaultCollisionConfiguration>();
  m.dispatcher = std::make_unique<btCollisionDispatcher>(m.collision_config.get());
  m.broadphase = std::make_unique<btDbvtBroadphase>();
  m.solver = std::make_unique<btSequentialImpulseConstraintSolver>();
  m.world = std::make_unique<btDiscreteDynamicsWorld>(m.dispatcher.get(), m.broadphase.get(),
                                                      m.solver.get(), m.collision_config.get());
  m.world->setGravity(Bt(params.config.gravity));

  for (const EntitySpec& spec : MultiObjectSpecs(params)) {
    const ColliderSpec& col = spec.colliders[0];
    auto shape = std::make_unique<btBoxShape>(Bt(col.half_extents));
    const bool dynamic = spec.rigid_body && !spec.rigid_body->kinematic &&
                         spec.rigid_body->mass > 0;
    const bool kinematic = spec.rigid_body && spec.rigid_body->kinematic;
    const btScalar mass = dynamic ? spec.rigid_body->mass : 0;
    btVector3 inertia(0, 0, 0);
    if (dynamic) shape->calculateLocalInertia(mass, inertia);
    auto motion = std::make_unique<btDefaultMotionState>(
        btTransform(Bt(spec.rotation), Bt(spec.position)));
    btRigidBody::btRigidBodyConstructionInfo ci(mass, motion.get(), shape.get(), inertia);
    ci.m_friction = spec.rigid_body ? spec.rigid_body->friction : 0.5f;
    ci.m_restitution = spec.rigid_body ? spec.rigid_body->restitution : 0.0f;
    auto body = std::make_unique<btRigidBody>(ci);
    if (kinematic) {
      body->setCollisionFlags(body->getCollisionFlags() | btCollisionObject::CF_KINEMATIC_OBJECT);
      body->setActivationState(DISABLE_DEACTIVATION);
      m.stirrer = body.get();
    }
    if (dynamic) m.boxes.push_back(body.get());
    m.world->addRigidBody(body.get());
    m.shapes.push_back(std::move(shape));
    m.motion_states.push_back(std::move(motion));
    m.bodies.push_back(std::move(body));
  }
}

RawBulletMultiObjectScene::~RawBulletMultiObjectScene() {
  for (auto& b : impl_->bodies) impl_->world->removeRigidBody(b.get());
  impl_->world.reset();
}

void RawBulletMultiObjectScene::Step() {
  Impl& m = *impl_;
  ++m.steps;
  Vec3f pos;
  Quatf rot;
  const btScalar dt = m.params.config.fixed_dt;
  StirrerPose(m.params, static_cast<double>(m.steps) * dt, &pos, &rot);
  m.stirrer->getMotionState()->setWorldTransform(btTransform(Bt(rot), Bt(pos)));
  m.world->stepSimulation(dt, 1, dt);  // Bullet's default call (one fixed step of dt)
}

size_t RawBulletMultiObjectScene::MovingBoxes(float min_speed) const {
  size_t n = 0;
  for (const btRigidBody* b : impl_->boxes) {
    if (b->isActive() && b->getLinearVelocity().length() > min_speed) ++n;
  }
  return n;
}

btDiscreteDynamicsWorld* RawBulletMultiObjectScene::world() const { return impl_->world.get(); }

// ---------------------------------------------------------------------------------------------

namespace {

bool InsideBunny(float x, float y, float z, float s) {
  auto ellipsoid = [](float px, float py, float pz, float a, float b, float c) {
    return (px * px) / (a * a) + (py * py) / (b * b) + (pz * pz) / (c * c) <= 1.0f;
  };
  // Body: ellipsoid along X; head: sphere in front and above; ears: tall thin ellipsoids.
  if (ellipsoid(x, y, z, s, 0.75f * s, 0.7f * s)) return true;
  if (ellipsoid(x - 0.9f * s, y - 0.55f * s, z, 0.45f * s, 0.45f * s, 0.45f * s)) return true;
  if (ellipsoid(x - 0.8f * s, y - 1.2f * s, z - 0.18f * s, 0.12f * s, 0.4f * s, 0.1f * s)) {
    return true;
  }
  return ellipsoid(x - 0.8f * s, y - 1.2f * s, z + 0.18f * s, 0.12f * s, 0.4f * s, 0.1f * s);
}

std::vector<Vec3f> BunnyLattice(float s, float h) {
  std::vector<Vec3f> pts;
  for (float x = -1.5f * s; x <= 1.5f * s; x += h) {
    for (float y = -1.0f * s; y <= 1.7f * s; y += h) {
      for (float z = -1.0f * s; z <= 1.0f * s; z += h) {
        if (InsideBunny(x, y, z, s)) pts.push_back(Vec3f{x, y, z});
      }
    }
  }
  return pts;
}

}  // namespace

SoftBodySpec MakeBunnySoftBody(const BunnyParams& p) {
  const float s = p.scale;
  // Spacing search: the count falls monotonically (roughly) with h; bisect on log h.
  float lo = s * 0.01f, hi = s;
  std::vector<Vec3f> pts;
  for (int it = 0; it < 30; ++it) {
    const float h = std::sqrt(lo * hi);
    pts = BunnyLattice(s, h);
    const int n = static_cast<int>(pts.size());
    if (std::abs(n - p.target_particles) <= p.target_particles / 20) break;
    if (n > p.target_particles) {
      lo = h;
    } else {
      hi = h;
    }
  }
  const float h = std::sqrt(lo * hi);
  pts = BunnyLattice(s, h);

  SoftBodySpec out;
  const size_t n = pts.size();
  out.particles.reserve(3 * n);
  for (const Vec3f& q : pts) {
    out.particles.push_back(p.center.x + q.x);
    out.particles.push_back(p.center.y + q.y);
    out.particles.push_back(p.center.z + q.z);
  }
  out.masses.assign(n, p.total_mass / static_cast<float>(std::max<size_t>(n, 1)));
  // Neighbours via integer lattice coordinates.
  auto key = [&](const Vec3f& q) {
    const int64_t ix = std::lround((q.x + 1.5f * s) / h);
    const int64_t iy = std::lround((q.y + 1.0f * s) / h);
    const int64_t iz = std::lround((q.z + 1.0f * s) / h);
    return (ix << 42) | (iy << 21) | iz;
  };
  std::unordered_map<int64_t, uint32_t> index;
  for (size_t i = 0; i < n; ++i) index.emplace(key(pts[i]), static_cast<uint32_t>(i));
  for (size_t i = 0; i < n; ++i) {
    const int64_t k = key(pts[i]);
    const int64_t ix = k >> 42, iy = (k >> 21) & ((1 << 21) - 1), iz = k & ((1 << 21) - 1);
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const int64_t nk = ((ix + dx) << 42) | ((iy + dy) << 21) | (iz + dz);
          auto it = index.find(nk);
          if (it != index.end() && it->second > i) {
            out.springs.push_back(static_cast<uint32_t>(i));
            out.springs.push_back(it->second);
          }
        }
      }
    }
  }
  out.stiffness = p.stiffness;
  out.damping = p.damping;
  return out;
}

SoftBodySpec MakeLatticeCubeSoftBody(float stiffness) {
  SoftBodySpec s;
  constexpr int n = 5;
  constexpr float spacing = 0.05f;
  auto index = [](int x, int y, int z) { return static_cast<uint32_t>((x * n + y) * n + z); };
  for (int x = 0; x < n; ++x) {
    for (int y = 0; y < n; ++y) {
      for (int z = 0; z < n; ++z) {
        s.particles.insert(s.particles.end(), {x * spacing, 0.3f + y * spacing, z * spacing});
        s.masses.push_back(0.01f);
      }
    }
  }
  for (int x = 0; x < n; ++x) {
    for (int y = 0; y < n; ++y) {
      for (int z = 0; z < n; ++z) {
        for (int dx = -1; dx <= 1; ++dx) {
          for (int dy = -1; dy <= 1; ++dy) {
            for (int dz = -1; dz <= 1; ++dz) {
              const int a = x + dx, b = y + dy, c = z + dz;
              if (a < 0 || b < 0 || c < 0 || a >= n || b >= n || c >= n) continue;
              if (index(a, b, c) <= index(x, y, z)) continue;
              s.springs.push_back(index(x, y, z));
              s.springs.push_back(index(a, b, c));
            }
          }
        }
      }
    }
  }
  s.stiffness = stiffness;
  s.damping = 0.05f;
  return s;
}

}  // namespace edgephys::physics
