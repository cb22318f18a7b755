#include "loadgen/scenes/scenes.h"

#include <btBulletDynamicsCommon.h>
#include <gtest/gtest.h>

#include <cstdio>

namespace edgephys::physics {
namespace {

TEST(ScenesTest, MultiObjectStirrerKeepsAQuarterMovingInBothVariants) {
  MultiObjectParams p;
  p.num_objects = 200;
  PhysSMultiObjectScene phys(p);
  RawBulletMultiObjectScene raw(p);
  EXPECT_EQ(phys.world().counters().dynamic_bodies, 200u);
  EXPECT_EQ(phys.world().counters().bodies,
            static_cast<size_t>(raw.world()->getNumCollisionObjects()));
  size_t min_phys = p.num_objects, min_raw = p.num_objects;
  for (int i = 1; i <= 300; ++i) {  // 5 s: drop, settle, stir
    phys.Step();
    raw.Step();
    if (i > 180) {
      min_phys = std::min(min_phys, phys.MovingBoxes(0.05f));
      min_raw = std::min(min_raw, raw.MovingBoxes(0.05f));
    }
  }
  std::printf("[multiobject N=200] min moving over 3..5 s: PhyS %zu, raw Bullet %zu\n", min_phys,
              min_raw);
  EXPECT_GE(min_phys, 50u);
  EXPECT_GE(min_raw, 50u);
  EXPECT_GT(phys.last_moved(), 0u);
}

TEST(ScenesTest, SpecsAreDeterministicAndBoxesStartInsideTheContainer) {
  MultiObjectParams p;
  p.num_objects = 1000;
  const auto a = MultiObjectSpecs(p);
  const auto b = MultiObjectSpecs(p);
  ASSERT_EQ(a.size(), b.size());
  const float w = MultiObjectHalfWidth(p);
  for (size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].position.x, b[i].position.x);
    if (a[i].id >= kSceneFirstBoxId) {
      EXPECT_LT(std::abs(a[i].position.x), w);
      EXPECT_LT(std::abs(a[i].position.z), w);
    }
  }
}

}  // namespace
}  // namespace edgephys::physics
