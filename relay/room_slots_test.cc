// Room-local entity slots (Entity::slot / serial) and the replication frame: freed slots are
// reused, every occupancy has its own serial (a respawn under the same id included), churn
// keeps the slot table bounded, and the frame lists the entities by id.
#include <gtest/gtest.h>

#include <set>
#include <vector>

#include "relay/room.h"

namespace edgephys {
namespace {

Entity Plain(uint32_t id) {
  Entity e;
  e.id = id;
  e.owner = 1;
  e.creator = 1;
  return e;
}

TEST(RoomSlots, FreedSlotsAreReusedUnderANewSerial) {
  Room room("r", RoomConfig{}, 0);
  const Entity& a = room.AddEntity(Plain(100));
  const Entity& b = room.AddEntity(Plain(200));
  EXPECT_NE(a.slot, b.slot);
  EXPECT_NE(a.serial, 0u);
  const uint32_t a_slot = a.slot, a_serial = a.serial;
  room.RemoveEntity(100);
  EXPECT_EQ(room.slots()[a_slot], nullptr);
  // The same id again: the freed slot, a new serial.
  const Entity& again = room.AddEntity(Plain(100));
  EXPECT_EQ(again.slot, a_slot);
  EXPECT_NE(again.serial, a_serial);
  EXPECT_EQ(room.slots()[again.slot], &again);
  EXPECT_EQ(room.slots().size(), 2u);
}

TEST(RoomSlots, ThousandSpawnDespawnCyclesKeepTheSlotTableBoundedAndSerialsUnique) {
  Room room("r", RoomConfig{}, 0);
  room.AddEntity(Plain(1));  // one that stays
  std::set<uint32_t> serials;
  for (int cycle = 0; cycle < 1000; ++cycle) {
    for (uint32_t i = 0; i < 5; ++i) {
      const Entity& e = room.AddEntity(Plain(1000 + i));  // same ids every cycle
      ASSERT_TRUE(serials.insert(e.serial).second) << "serial reused, cycle " << cycle;
    }
    for (uint32_t i = 0; i < 5; ++i) room.RemoveEntity(1000 + i);
    ASSERT_LE(room.slots().size(), 6u) << cycle;
  }
  EXPECT_EQ(room.entities().size(), 1u);
}

TEST(RoomSlots, TheFrameListsEveryEntityByIdAndTheSoftBodies) {
  Room room("r", RoomConfig{}, 0);
  for (uint32_t id : {50u, 7u, 300u, 12u}) room.AddEntity(Plain(id));
  Entity soft = Plain(99);
  soft.nodes = {{0, 0, 0}, {1, 0, 0}};
  soft.nodes_version = 1;
  room.AddEntity(soft);
  room.BuildFrame();
  std::vector<uint32_t> ids;
  for (const Entity* e : room.frame().by_id) ids.push_back(e->id);
  EXPECT_EQ(ids, (std::vector<uint32_t>{7, 12, 50, 99, 300}));
  ASSERT_EQ(room.frame().soft.size(), 1u);
  EXPECT_EQ(room.frame().soft[0]->id, 99u);
  room.RemoveEntity(12);
  room.BuildFrame();
  ids.clear();
  for (const Entity* e : room.frame().by_id) ids.push_back(e->id);
  EXPECT_EQ(ids, (std::vector<uint32_t>{7, 50, 99, 300}));
}

}  // namespace
}  // namespace edgephys
