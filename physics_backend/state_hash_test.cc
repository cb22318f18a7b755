#include "physics_backend/state_hash.h"

#include <gtest/gtest.h>

#include "physics_backend/testing/physics_test_util.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {
namespace {

TEST(StateHashTest, Fnv1aKnownVectors) {
  EXPECT_EQ(Fnv1a("", 0), 0xcbf29ce484222325ull);
  EXPECT_EQ(Fnv1a("a", 1), 0xaf63dc4c8601ec8cull);
  EXPECT_EQ(Fnv1a("foobar", 6), 0x85944171f73967e8ull);
}

void AddBunny(PhysicsWorld& world) {
  BunnyParams bp;
  bp.center = {0.5f, 2.0f, 0.5f};
  bp.target_particles = 200;
  EntitySpec e;
  e.id = 50;
  e.soft_body = MakeBunnySoftBody(bp);
  ASSERT_TRUE(testing::Add(world, e).ok());
}

TEST(StateHashTest, IdenticalWorldsHashIdenticallyAndPerturbationsShow) {
  MultiObjectParams p;
  p.num_objects = 60;
  PhysSMultiObjectScene a(p), b(p);
  MultiObjectParams q = p;
  q.seed = 2;
  PhysSMultiObjectScene c(q);
  AddBunny(a.world());
  AddBunny(b.world());
  AddBunny(c.world());
  EXPECT_EQ(HashWorldState(a.world()), HashWorldState(b.world()));
  for (int i = 1; i <= 180; ++i) {
    a.Step();
    b.Step();
    c.Step();
    if (i % 60 == 0) {
      EXPECT_EQ(HashWorldState(a.world()), HashWorldState(b.world())) << "step " << i;
      EXPECT_NE(HashWorldState(a.world()), HashWorldState(c.world())) << "step " << i;
    }
  }
  // One extra tiny nudge diverges the hash.
  ASSERT_TRUE(b.world().SetVelocity(kSceneFirstBoxId, {0, 1e-3f, 0}, {}).ok());
  a.Step();
  b.Step();
  EXPECT_NE(HashWorldState(a.world()), HashWorldState(b.world()));
}

}  // namespace
}  // namespace edgephys::physics
