// Behavioural tests of PhysicsWorld: validation, commands, events, hierarchy, joints, guard.
#include "physics_backend/physics_world.h"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>

#include "physics_backend/testing/physics_test_util.h"
#include "physics_backend/state_hash.h"

namespace edgephys::physics {
namespace {

using namespace testing;  // physics_test_util.h: Add, Ground, Pos, Vel

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();
constexpr uint32_t kInteractable = static_cast<uint32_t>(schema::EntityFlags::Interactable);

// ---------------------------------------------------------------------------------------------
// Validation

struct InvalidCase {
  const char* name;
  std::function<void(EntitySpec*)> mutate;
  InvalidReason reason;
  StatusCode code;
};

// A mutation that makes the entity static with a triangle-mesh first collider of `vertices`
// (x, y, z floats) and `indices`.
std::function<void(EntitySpec*)> StaticMesh(std::vector<float> vertices,
                                            std::vector<uint32_t> indices) {
  return [vertices, indices](EntitySpec* s) {
    s->rigid_body.reset();
    s->colliders[0].shape = schema::ColliderShape::TriangleMesh;
    s->colliders[0].vertices = vertices;
    s->colliders[0].indices = indices;
  };
}

TEST(PhysicsWorldTest, InvalidContainersRejectedWithReasonAndNoSideEffects) {
  PhysicsConfig cfg;
  cfg.max_soft_nodes = 16;
  PhysicsWorld world(cfg);
  PhysicsWorld reference(cfg);
  for (PhysicsWorld* w : {&world, &reference}) {
    ASSERT_TRUE(Add(*w, Ground(1)).ok());
    ASSERT_TRUE(Add(*w, DynamicBox(2, {0, 2, 0}, {0.2f, 0.2f, 0.2f}, 1.0f)).ok());
  }
  const std::vector<InvalidCase> cases = {
      {"nan position", [](EntitySpec* s) { s->position.y = kNaN; }, InvalidReason::kNaN,
       StatusCode::kInvalidArgument},
      {"nan half extent", [](EntitySpec* s) { s->colliders[0].half_extents.x = kNaN; },
       InvalidReason::kNaN, StatusCode::kInvalidArgument},
      {"negative mass", [](EntitySpec* s) { s->rigid_body->mass = -1; },
       InvalidReason::kNegativeMass, StatusCode::kInvalidArgument},
      {"coplanar hull",
       [](EntitySpec* s) {
         s->colliders[0].shape = schema::ColliderShape::ConvexHull;
         s->colliders[0].vertices = {0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 1, 0.5f, 0, 0.5f};
       },
       InvalidReason::kDegenerateMesh, StatusCode::kInvalidArgument},
      {"zero-area mesh", StaticMesh({0, 0, 0, 1, 0, 0, 2, 0, 0}, {0, 1, 2}),
       InvalidReason::kDegenerateMesh, StatusCode::kInvalidArgument},
      {"mesh index out of range", StaticMesh({0, 0, 0, 1, 0, 0, 0, 0, 1}, {0, 1, 7}),
       InvalidReason::kDegenerateMesh, StatusCode::kInvalidArgument},
      {"too many soft nodes",
       [](EntitySpec* s) {
         s->rigid_body.reset();
         s->colliders.clear();
         s->soft_body = SoftBodySpec{};
         for (int i = 0; i < 17; ++i) {
           s->soft_body->particles.insert(s->soft_body->particles.end(),
                                          {static_cast<float>(i), 1, 0});
         }
       },
       InvalidReason::kTooManyNodes, StatusCode::kTooLarge},
      {"soft particle mass under 1 mg",
       [](EntitySpec* s) {
         s->rigid_body.reset();
         s->colliders.clear();
         s->soft_body = SoftBodySpec{{0, 1, 0, 1, 1, 0}, {1, 1e-39f}, {0, 1}, 10, 0};
       },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"spring index out of range",
       [](EntitySpec* s) {
         s->rigid_body.reset();
         s->colliders.clear();
         s->soft_body = SoftBodySpec{{0, 1, 0, 1, 1, 0}, {1, 1}, {0, 5}, 10, 0};
       },
       InvalidReason::kBadSoftBody, StatusCode::kInvalidArgument},
      {"unknown shape",
       [](EntitySpec* s) { s->colliders[0].shape = static_cast<schema::ColliderShape>(42); },
       InvalidReason::kUnknownShape, StatusCode::kInvalidArgument},
      {"duplicate id", [](EntitySpec* s) { s->id = 2; }, InvalidReason::kDuplicateId,
       StatusCode::kAlreadyExists},
      {"zero id", [](EntitySpec* s) { s->id = 0; }, InvalidReason::kZeroId,
       StatusCode::kInvalidArgument},
      {"unknown parent", [](EntitySpec* s) { s->parent_id = 999; }, InvalidReason::kUnknownParent,
       StatusCode::kInvalidArgument},
      {"joint to unknown entity",
       [](EntitySpec* s) { s->joints.push_back(JointSpec{schema::JointKind::Fixed, 999}); },
       InvalidReason::kUnknownJointTarget, StatusCode::kInvalidArgument},
      {"negative box size", [](EntitySpec* s) { s->colliders[0].half_extents.y = -1; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"restitution > 1", [](EntitySpec* s) { s->rigid_body->restitution = 2; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      // Initial velocities: finite but beyond the stability guard's speeds (issue 35 item 8).
      {"linear velocity 1e30", [](EntitySpec* s) { s->rigid_body->linear_velocity = {1e30f, 0, 0}; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"linear velocity over max speed",
       [](EntitySpec* s) { s->rigid_body->linear_velocity = {0, 150, 150}; },  // 212 m/s
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"angular velocity 1e30",
       [](EntitySpec* s) { s->rigid_body->angular_velocity = {0, 0, -1e30f}; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"infinite linear velocity",
       [](EntitySpec* s) {
         s->rigid_body->linear_velocity = {std::numeric_limits<float>::infinity(), 0, 0};
       },
       InvalidReason::kNaN, StatusCode::kInvalidArgument},
      // Denormal components square to 0 in float; such a quaternion is not the all-zero
      // "identity" and normalises to NaN (a crash in Bullet's soft-body SDF the fuzzer found).
      {"denormal collider rotation",
       [](EntitySpec* s) { s->colliders[0].local_rotation = {0, 0, 0, -5.8e-39f}; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"denormal body rotation", [](EntitySpec* s) { s->rotation = {1e-30f, 0, 0, 1e-30f}; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      // Sizes and offsets are bounded by the world's width (2 km at the default bounds), after
      // scaling, and sizes from below by 0.1 mm.
      {"box wider than the world", [](EntitySpec* s) { s->colliders[0].half_extents.x = 2001; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"collider offset beyond the world",
       [](EntitySpec* s) { s->colliders[0].local_position = {0, 1e30f, 0}; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"scale overflows a sphere",
       [](EntitySpec* s) {
         s->colliders[0].shape = schema::ColliderShape::Sphere;
         s->scale = {1e30f, 1e30f, 1e30f};
       },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"scale shrinks a box below 0.1 mm", [](EntitySpec* s) { s->scale = {1, 1e-4f, 1}; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"capsule taller than the world",
       [](EntitySpec* s) {
         s->colliders[0].shape = schema::ColliderShape::Capsule;
         s->colliders[0].radius = 0.1f;
         s->colliders[0].height = 1e30f;
       },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"dynamic mass under 1 mg", [](EntitySpec* s) { s->rigid_body->mass = 1e-39f; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"dynamic mass over a million tonnes", [](EntitySpec* s) { s->rigid_body->mass = 1e38f; },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
      {"hull vertex beyond the world",
       [](EntitySpec* s) {
         s->colliders[0].shape = schema::ColliderShape::ConvexHull;
         s->colliders[0].vertices = {0, 0, 0, 1e30f, 0, 0, 0, 1, 0, 0, 0, 1};
       },
       InvalidReason::kOutOfRange, StatusCode::kInvalidArgument},
  };
  for (const InvalidCase& c : cases) {
    EntitySpec spec = DynamicBox(50, {1, 3, 0}, {0.2f, 0.2f, 0.2f}, 1.0f);
    c.mutate(&spec);
    InvalidReason reason = InvalidReason::kNone;
    const Status st = Add(world, spec, &reason);
    EXPECT_FALSE(st.ok()) << c.name;
    EXPECT_EQ(reason, c.reason) << c.name << ": got " << InvalidReasonName(reason);
    EXPECT_EQ(st.code(), c.code) << c.name;
    EXPECT_EQ(world.counters().entities, 2u) << c.name;
    world.Step();
    reference.Step();
  }
  EXPECT_EQ(world.counters().rejected_containers, cases.size());
  // Nothing leaked into the simulation: both worlds are bit-identical.
  EXPECT_EQ(HashWorldState(world), HashWorldState(reference));
  // And the world still accepts valid containers, at the size bounds too.
  EXPECT_TRUE(Add(world, DynamicBox(50, {1, 3, 0}, {0.2f, 0.2f, 0.2f}, 1.0f)).ok());
  EXPECT_TRUE(Add(world, StaticBox(51, {0, -600, 0}, {2000, 1, 2000})).ok());
  EXPECT_TRUE(Add(world, DynamicBox(52, {3, 3, 0}, {2e-4f, 2e-4f, 2e-4f}, 0.01f)).ok());
}

TEST(PhysicsWorldTest, BuildsEveryColliderKindAndCompound) {
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  EntitySpec multi = DynamicBox(2, {0, 2, 0}, {0.1f, 0.1f, 0.1f}, 2.0f);
  ColliderSpec sphere = SphereCollider(0.1f);
  sphere.local_position = {0.3f, 0, 0};
  ColliderSpec capsule;
  capsule.shape = schema::ColliderShape::Capsule;
  capsule.radius = 0.05f;
  capsule.height = 0.2f;
  capsule.local_position = {-0.3f, 0, 0};
  ColliderSpec cylinder;
  cylinder.shape = schema::ColliderShape::Cylinder;
  cylinder.half_extents = {0.1f, 0.1f, 0.1f};
  cylinder.local_position = {0, 0.3f, 0};
  ColliderSpec hull;
  hull.shape = schema::ColliderShape::ConvexHull;
  hull.vertices = {0, 0, 0, 0.2f, 0, 0, 0, 0.2f, 0, 0, 0, 0.2f};
  hull.local_position = {0, -0.3f, 0};
  multi.colliders = {multi.colliders[0], sphere, capsule, cylinder, hull};
  ASSERT_TRUE(Add(world, multi).ok());
  // A static triangle-mesh ramp and a dynamic mesh (becomes its convex hull).
  EntitySpec ramp;
  ramp.id = 3;
  ramp.position = {5, 0, 0};
  ColliderSpec mesh;
  mesh.shape = schema::ColliderShape::TriangleMesh;
  mesh.vertices = {-1, 0, -1, 1, 0, -1, 1, 1, 1, -1, 1, 1};
  mesh.indices = {0, 1, 2, 0, 2, 3};
  ramp.colliders = {mesh};
  ASSERT_TRUE(Add(world, ramp).ok());
  EntitySpec dyn_mesh = DynamicBox(4, {5, 3, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  ColliderSpec tetra;
  tetra.shape = schema::ColliderShape::TriangleMesh;
  tetra.vertices = {0, 0, 0, 0.3f, 0, 0, 0, 0.3f, 0, 0, 0, 0.3f};
  tetra.indices = {0, 1, 2, 0, 1, 3, 0, 2, 3, 1, 2, 3};
  dyn_mesh.colliders = {tetra};
  ASSERT_TRUE(Add(world, dyn_mesh).ok());
  for (int i = 0; i < 180; ++i) world.Step();
  // The compound rests on the ground (lowest part: hull at -0.3 with its tip at y = -0.3).
  // (It may tip over onto any part; its origin ends between 0.05 and 0.45 above the ground.)
  EXPECT_GT(Pos(world, 2).y, 0.05f);
  EXPECT_LT(Pos(world, 2).y, 0.45f);
  EXPECT_GT(Pos(world, 4).y, 0.0f);  // landed on the ramp or the ground, did not fall through
  EXPECT_EQ(world.counters().bodies, 4u);
}

// Quaternions are normalised in double: components near FLT_MAX square to inf in float and
// used to normalise to zeros, a NaN rotation matrix that crashed Bullet's soft-body SDF (a
// fuzzer finding). They are a usable direction, so they are accepted.
TEST(PhysicsWorldTest, HugeQuaternionComponentsBecomeAUnitRotation) {
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  EntitySpec soft;
  soft.id = 2;
  soft.soft_body = SoftBodySpec{{0, 0.5f, 0, 0.1f, 0.5f, 0, 0, 0.6f, 0, 0, 0.5f, 0.1f},
                                {0.1f, 0.1f, 0.1f, 0.1f}, {0, 1, 0, 2, 0, 3, 1, 2, 1, 3, 2, 3},
                                50, 0.1f};
  ASSERT_TRUE(Add(world, soft).ok());
  EntitySpec paddle = StaticBox(3, {0, 0.5f, 0}, {0.3f, 0.3f, 0.3f});
  paddle.rotation = {0, 0, -1.7e38f, 0};
  paddle.rigid_body = RigidBodySpec{};
  paddle.rigid_body->mass = 0;
  paddle.rigid_body->kinematic = true;
  paddle.colliders[0].local_rotation = {3e38f, 0, 0, 3e38f};
  paddle.colliders[0].local_position = {0, 0.01f, 0};  // a compound, as in the finding
  ASSERT_TRUE(Add(world, paddle).ok());
  EntityState st;
  ASSERT_TRUE(world.GetState(3, &st).ok());
  EXPECT_NEAR(std::abs(st.rotation.z), 1.0f, 1e-6f);
  ASSERT_TRUE(world.MoveToTransform(3, {0, 0.5f, 0}, {1e38f, 1e38f, 0, 0}).ok());
  std::vector<Vec3f> nodes;
  for (int i = 0; i < 30; ++i) {
    world.Step();
    ASSERT_TRUE(world.GetSoftBodyNodes(2, &nodes).ok());
    for (const Vec3f& p : nodes) ASSERT_TRUE(std::isfinite(p.x + p.y + p.z)) << "step " << i;
  }
  ASSERT_TRUE(world.GetState(3, &st).ok());
  EXPECT_NEAR(std::abs(st.rotation.x), std::sqrt(0.5f), 1e-6f);
  EXPECT_NEAR(std::abs(st.rotation.y), std::sqrt(0.5f), 1e-6f);
}

// ---------------------------------------------------------------------------------------------
// Commands

TEST(PhysicsWorldTest, KinematicFollowsMoveToTransformAndPushes) {
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  EntitySpec paddle = StaticBox(2, {-1, 0.25f, 0}, {0.1f, 0.25f, 0.5f});
  paddle.rigid_body = RigidBodySpec{};
  paddle.rigid_body->mass = 0;
  paddle.rigid_body->kinematic = true;
  ASSERT_TRUE(Add(world, paddle).ok());
  ASSERT_TRUE(Add(world, DynamicBox(3, {0, 0.2f, 0}, {0.2f, 0.2f, 0.2f}, 1.0f)).ok());
  for (int i = 1; i <= 90; ++i) {
    const Vec3f target{-1.0f + 0.02f * i, 0.25f, 0.0f};
    const Quatf rot = testing::AxisAngle(0, 1, 0, 0.001f * i);
    ASSERT_TRUE(world.MoveToTransform(2, target, rot).ok());
    world.Step();
    const Vec3f p = Pos(world, 2);
    EXPECT_FLOAT_EQ(p.x, target.x);
    EXPECT_FLOAT_EQ(p.y, target.y);
    EXPECT_FLOAT_EQ(p.z, target.z);
  }
  // The paddle swept from x = -1 to 0.8: the box (starting at 0) was pushed ahead of it.
  EXPECT_GT(Pos(world, 3).x, 0.8f + 0.1f + 0.2f - 0.02f);
  // Dynamic entities only move through a grab.
  EXPECT_EQ(world.MoveToTransform(3, {0, 1, 0}, {}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(world.MoveToTransform(3, {kNaN, 1, 0}, {}).code(), StatusCode::kInvalidArgument);
  // Finite but outside the world bounds: refused, the paddle stays where it was.
  const Vec3f before = Pos(world, 2);
  EXPECT_EQ(world.MoveToTransform(2, {1e30f, 0.25f, 0}, {}).code(), StatusCode::kInvalidArgument);
  EXPECT_EQ(world.SetTransform(2, {0, -1001, 0}, {}).code(), StatusCode::kInvalidArgument);
  world.Step();
  EXPECT_EQ(testing::Dist(Pos(world, 2), before), 0.0f);
}

TEST(PhysicsWorldTest, GrabbedCubeFollowsTargetAndStopsAtWall) {
  PhysicsWorld world;
  // Wall: face at x = 0.95.
  ASSERT_TRUE(Add(world, StaticBox(1, {1.0f, 1.0f, 0}, {0.05f, 1.0f, 1.0f})).ok());
  EntitySpec cube = DynamicBox(2, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  cube.flags = kInteractable;
  ASSERT_TRUE(Add(world, cube).ok());
  EntitySpec plain = DynamicBox(3, {-3, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  ASSERT_TRUE(Add(world, plain).ok());
  EXPECT_EQ(world.Grab(3, 0).code(), StatusCode::kPermissionDenied);
  ASSERT_TRUE(world.Grab(2, 0).ok());
  // Free-space target: reached (gravity off while held).
  for (int i = 0; i < 30; ++i) {
    ASSERT_TRUE(world.MoveToTransform(2, {0.3f, 1.2f, 0}, {}).ok());
    world.Step();
  }
  EXPECT_NEAR(Pos(world, 2).x, 0.3f, 1e-3);
  EXPECT_NEAR(Pos(world, 2).y, 1.2f, 1e-3);
  // Target behind the wall: the cube stops at the face.
  float max_x = 0;
  for (int i = 0; i < 120; ++i) {
    ASSERT_TRUE(world.MoveToTransform(2, {3.0f, 1.2f, 0}, {}).ok());
    world.Step();
    max_x = std::max(max_x, Pos(world, 2).x);
  }
  const float rest_x = 0.95f - 0.1f;
  std::printf("[grab] cube against wall: x = %.4f (contact at %.3f), max %.4f\n",
              Pos(world, 2).x, rest_x, max_x);
  EXPECT_LT(max_x, rest_x + 0.015f);  // one step of overshoot, then pushed out
  EXPECT_GT(Pos(world, 2).x, rest_x - 0.02f);
  ASSERT_TRUE(world.Release(2).ok());
  EXPECT_FALSE(world.IsGrabbed(2));
  for (int i = 0; i < 30; ++i) world.Step();
  EXPECT_LT(Pos(world, 2).y, 1.0f);  // gravity is back
}

TEST(PhysicsWorldTest, RemovingTheHandReleasesTheGrab) {
  PhysicsWorld world;
  EntitySpec hand;
  hand.id = 7;
  hand.rigid_body = RigidBodySpec{};
  hand.rigid_body->mass = 0;
  hand.rigid_body->kinematic = true;
  ASSERT_TRUE(Add(world, hand).ok());
  EntitySpec cube = DynamicBox(2, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  cube.flags = kInteractable;
  ASSERT_TRUE(Add(world, cube).ok());
  ASSERT_TRUE(world.Grab(2, 7).ok());
  ASSERT_TRUE(world.RemoveEntity(7).ok());
  EXPECT_FALSE(world.IsGrabbed(2));
  EXPECT_FALSE(world.HasEntity(7));
}

// ---------------------------------------------------------------------------------------------
// Events

TEST(PhysicsWorldTest, TriggerEnterAndExitExactlyOnceInOrder) {
  PhysicsWorld world;
  EntitySpec zone = StaticBox(1, {0, 5, 0}, {0.5f, 0.5f, 0.5f});
  zone.colliders[0].is_trigger = true;
  ASSERT_TRUE(Add(world, zone).ok());
  ASSERT_TRUE(Add(world, DynamicSphere(2, {0, 7, 0}, 0.1f, 1.0f)).ok());
  std::vector<PhysicsEvent> events;
  for (int i = 0; i < 120; ++i) world.Step();  // falls through the zone (no response)
  world.DrainEvents(&events);
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].type, PhysicsEventType::kTriggerEnter);
  EXPECT_EQ(events[0].entity_a, 1u);
  EXPECT_EQ(events[0].entity_b, 2u);
  EXPECT_EQ(events[1].type, PhysicsEventType::kTriggerExit);
  EXPECT_EQ(events[1].entity_a, 1u);
  EXPECT_EQ(events[1].entity_b, 2u);
  EXPECT_LT(events[0].step, events[1].step);
  EXPECT_LT(Pos(world, 2).y, 4.0f);  // passed through, not stopped
}

TEST(PhysicsWorldTest, HandTriggerHoversWhileSolidPartCollides) {
  PhysicsWorld world;
  // Kinematic hand: a solid palm and a trigger sphere below it (paper, fig. 2).
  EntitySpec hand;
  hand.id = 10;
  hand.position = {0, 2, 0};
  hand.flags = static_cast<uint32_t>(schema::EntityFlags::Hand);
  hand.rigid_body = RigidBodySpec{};
  hand.rigid_body->mass = 0;
  hand.rigid_body->kinematic = true;
  hand.colliders.push_back(BoxCollider({0.05f, 0.02f, 0.05f}));
  ColliderSpec hover = SphereCollider(0.15f);
  hover.local_position = {0, -0.15f, 0};
  hover.is_trigger = true;
  hand.colliders.push_back(hover);
  ASSERT_TRUE(Add(world, hand).ok());
  EntitySpec cube = DynamicBox(20, {0, 1.0f, 0}, {0.05f, 0.05f, 0.05f}, 1.0f);
  cube.rigid_body->use_gravity = false;
  cube.flags = kInteractable;
  ASSERT_TRUE(Add(world, cube).ok());
  std::vector<PhysicsEvent> events;
  // Lower the hand until its trigger overlaps the cube.
  for (int i = 1; i <= 40; ++i) {
    ASSERT_TRUE(world.MoveToTransform(10, {0, 2.0f - 0.02f * i, 0}, {}).ok());
    world.Step();
  }
  world.DrainEvents(&events);
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events[0].type, PhysicsEventType::kTriggerEnter);
  EXPECT_EQ(events[0].entity_a, 10u);
  EXPECT_EQ(events[0].entity_b, 20u);
}

TEST(PhysicsWorldTest, CollisionEnterOnLandingExitOnLiftOff) {
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  ASSERT_TRUE(Add(world, DynamicSphere(2, {0, 0.5f, 0}, 0.1f, 1.0f)).ok());
  std::vector<PhysicsEvent> events;
  for (int i = 0; i < 60; ++i) world.Step();
  world.DrainEvents(&events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, PhysicsEventType::kCollisionEnter);
  EXPECT_EQ(events[0].entity_a, 1u);
  EXPECT_EQ(events[0].entity_b, 2u);
  events.clear();
  ASSERT_TRUE(world.SetVelocity(2, {0, 5, 0}, {}).ok());
  for (int i = 0; i < 10; ++i) world.Step();
  world.DrainEvents(&events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].type, PhysicsEventType::kCollisionExit);
}

// ---------------------------------------------------------------------------------------------
// State output

TEST(PhysicsWorldTest, SleepingBodiesAreNotReported) {
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  ASSERT_TRUE(Add(world, DynamicBox(2, {0, 0.5f, 0}, {0.2f, 0.2f, 0.2f}, 1.0f)).ok());
  std::vector<EntityState> moved;
  world.Step();
  world.CollectStates(&moved);
  ASSERT_EQ(moved.size(), 1u);
  EXPECT_EQ(moved[0].entity_id, 2u);
  int steps = 1;
  while (world.counters().sleeping_bodies == 0 && steps < 600) {
    world.Step();
    ++steps;
  }
  ASSERT_EQ(world.counters().sleeping_bodies, 1u) << "did not fall asleep in 10 s";
  world.CollectStates(&moved);  // flush the last motion
  for (int i = 0; i < 60; ++i) {
    world.Step();
    world.CollectStates(&moved);
    EXPECT_TRUE(moved.empty()) << "sleeping body reported at step " << i;
  }
  ASSERT_TRUE(world.SetVelocity(2, {1, 0, 0}, {}).ok());
  world.Step();
  world.CollectStates(&moved);
  EXPECT_EQ(moved.size(), 1u);
}

TEST(PhysicsWorldTest, TransformOnlyChildrenFollowTheirParent) {
  PhysicsWorld world;
  EntitySpec parent;
  parent.id = 1;
  parent.position = {1, 0, 0};
  ASSERT_TRUE(Add(world, parent).ok());
  EntitySpec child;
  child.id = 2;
  child.parent_id = 1;
  child.position = {1, 1, 0};  // room frame: (0, 1, 0) relative to the parent
  ASSERT_TRUE(Add(world, child).ok());
  EntitySpec grandchild;
  grandchild.id = 3;
  grandchild.parent_id = 2;
  grandchild.position = {2, 1, 0};
  ASSERT_TRUE(Add(world, grandchild).ok());
  // Rotate the parent 90 degrees about Z and move it.
  ASSERT_TRUE(world.MoveToTransform(1, {5, 0, 0}, testing::AxisAngle(0, 0, 1, M_PI / 2)).ok());
  std::vector<EntityState> moved;
  world.Step();
  world.CollectStates(&moved);
  ASSERT_EQ(moved.size(), 3u);
  // Child: parent * (0,1,0) = (5,0,0) + Rz90 (0,1,0) = (4, 0, 0).
  EXPECT_NEAR(Pos(world, 2).x, 4.0f, 1e-5);
  EXPECT_NEAR(Pos(world, 2).y, 0.0f, 1e-5);
  // Grandchild: (1,0,0) relative to the child -> Rz90 -> (0,1,0) -> (4, 1, 0).
  EXPECT_NEAR(Pos(world, 3).x, 4.0f, 1e-5);
  EXPECT_NEAR(Pos(world, 3).y, 1.0f, 1e-5);
  // Removing the parent keeps the children where they are.
  ASSERT_TRUE(world.RemoveEntity(1).ok());
  EXPECT_NEAR(Pos(world, 2).x, 4.0f, 1e-5);
}

// ---------------------------------------------------------------------------------------------
// Joints

TEST(PhysicsWorldTest, SpringJointSagsByMgOverK) {
  PhysicsWorld world;
  EntitySpec bob = DynamicBox(1, {0, 2, 0}, {0.05f, 0.05f, 0.05f}, 2.0f);
  bob.joints.push_back(JointSpec{schema::JointKind::Spring, 0, {0, 0, 0}, {0, 0, 1}, 400.0f,
                                 5.0f});
  ASSERT_TRUE(Add(world, bob).ok());
  for (int i = 0; i < 600; ++i) world.Step();
  const double sag = 2.0 - Pos(world, 1).y;
  const double expected = 2.0 * 9.81 / 400.0;  // m g / k = 4.9 cm
  std::printf("[spring] sag %.4f m, m g / k = %.4f m\n", sag, expected);
  EXPECT_NEAR(sag, expected, 0.05 * expected);
}

TEST(PhysicsWorldTest, HingeKeepsPendulumLengthAndFixedJointHolds) {
  PhysicsWorld world;
  // Pendulum: box centre 0.5 m below the pivot at (0, 2, 0); hinge axis Z.
  EntitySpec bob = DynamicBox(1, {0, 1.5f, 0}, {0.05f, 0.05f, 0.05f}, 1.0f);
  bob.joints.push_back(JointSpec{schema::JointKind::Hinge, 0, {0, 0.5f, 0}, {0, 0, 1}});
  bob.rigid_body->linear_velocity = {2.0f, 0, 0};
  ASSERT_TRUE(Add(world, bob).ok());
  EntitySpec held = DynamicBox(2, {3, 2, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  held.joints.push_back(JointSpec{schema::JointKind::Fixed, 0});
  ASSERT_TRUE(Add(world, held).ok());
  const Vec3f pivot{0, 2, 0};
  double max_len_err = 0, max_swing = 0;
  for (int i = 0; i < 240; ++i) {
    world.Step();
    max_len_err = std::max<double>(max_len_err, std::abs(testing::Dist(Pos(world, 1), pivot) - 0.5));
    max_swing = std::max<double>(max_swing, std::abs(Pos(world, 1).x));
    EXPECT_NEAR(Pos(world, 1).z, 0.0f, 1e-3);  // stays in the hinge plane
  }
  EXPECT_LT(max_len_err, 0.01);
  EXPECT_GT(max_swing, 0.2);  // it swings
  EXPECT_LT(testing::Dist(Pos(world, 2), {3, 2, 0}), 0.01f);
  EXPECT_EQ(world.counters().joints, 2u);
  ASSERT_TRUE(world.RemoveEntity(1).ok());
  EXPECT_EQ(world.counters().joints, 1u);
}

// ---------------------------------------------------------------------------------------------
// Stability guard (rigid bodies)

TEST(PhysicsWorldTest, GuardRestoresNonFiniteAndRunawayBodies) {
  PhysicsWorld world;
  ASSERT_TRUE(Add(world, Ground(1)).ok());
  ASSERT_TRUE(Add(world, DynamicBox(2, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1.0f)).ok());
  for (int i = 0; i < 10; ++i) world.Step();
  const Vec3f before = Pos(world, 2);
  btRigidBody* body = world.RigidBodyForTesting(2);
  ASSERT_NE(body, nullptr);
  body->setLinearVelocity(btVector3(kNaN, 0, 0));  // what a broken constraint can produce
  world.Step();
  ASSERT_TRUE(OneNonFiniteGuardReset(world, 2));
  EXPECT_EQ(Pos(world, 2).y, before.y);  // restored to the last good state
  EXPECT_EQ(world.counters().guard_resets, 1u);
  std::vector<EntityState> moved;
  world.CollectStates(&moved);
  for (const EntityState& s : moved) EXPECT_TRUE(IsValidState(s));

  body->setLinearVelocity(btVector3(0, 500, 0));
  world.Step();
  std::vector<PhysicsEvent> events;
  world.DrainEvents(&events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].cause, GuardCause::kRunawaySpeed);
  EXPECT_EQ(world.counters().guard_resets, 2u);
  EXPECT_EQ(Vel(world, 2).y, 0.0f);
  // The body simulates normally afterwards.
  for (int i = 0; i < 60; ++i) world.Step();
  EXPECT_NEAR(Pos(world, 2).y, 0.1f, 0.01f);
}

TEST(PhysicsWorldTest, GuardParksBodiesLeavingTheWorldBounds) {
  PhysicsConfig cfg;
  cfg.world_half_extent = 20.0f;
  PhysicsWorld world(cfg);
  ASSERT_TRUE(Add(world, DynamicSphere(1, {0, 15, 0}, 0.1f, 1.0f)).ok());  // no ground
  for (int i = 0; i < 180; ++i) world.Step();
  std::vector<PhysicsEvent> events;
  world.DrainEvents(&events);
  ASSERT_EQ(events.size(), 1u);
  EXPECT_EQ(events[0].cause, GuardCause::kOutOfBounds);
  EXPECT_GT(Pos(world, 1).y, -20.0f);
  EXPECT_EQ(world.counters().sleeping_bodies, 1u);
}

TEST(PhysicsWorldTest, AdvanceRunsFixedStepsAndDropsBacklog) {
  PhysicsConfig cfg;
  cfg.max_substeps = 3;
  PhysicsWorld world(cfg);
  EXPECT_EQ(world.Advance(1.0 / 60.0 * 2.5), 2);
  EXPECT_EQ(world.Advance(1.0 / 60.0 * 0.6), 1);  // 0.5 + 0.6 carried over
  EXPECT_EQ(world.Advance(1.0), 3);               // capped; backlog dropped
  EXPECT_EQ(world.Advance(1.0 / 120.0), 0);
  EXPECT_EQ(world.counters().steps, 6u);
}

}  // namespace
}  // namespace edgephys::physics
