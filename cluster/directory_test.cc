// The directory against a real redis-server on a free loopback port.
#include "cluster/directory.h"

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <map>
#include <thread>

#include "cluster/redis_client.h"
#include "cluster/testing/redis_server.h"

namespace edgephys::cluster {
namespace {

using testing::RedisServer;

// Polls `done` every 20 ms for at most `seconds`.
bool WaitFor(const std::function<bool()>& done, double seconds = 5.0) {
  auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
  while (std::chrono::steady_clock::now() < end) {
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  return done();
}

DirectoryOptions Options(uint16_t port, const std::string& id) {
  DirectoryOptions o;
  o.redis_port = port;
  o.relay_id = id;
  o.public_address = "127.0.0.1:" + std::to_string(7000 + id.back());
  o.heartbeat_s = 0.05;
  o.ttl_s = 0.3;
  o.refresh_s = 0.05;
  o.redis_timeout_s = 0.3;
  return o;
}

std::unique_ptr<Directory> Open(uint16_t port, const std::string& id) {
  auto d = Directory::Start(Options(port, id));
  EXPECT_TRUE(d.ok());
  return d.ok() ? std::move(*d) : nullptr;
}

// Waits for the next placement answer for `room` on `d`.
// Events for other rooms are kept for later calls.
DirectoryEvent AwaitEvent(Directory& d, const std::string& room) {
  static std::map<Directory*, std::vector<DirectoryEvent>> kept;
  DirectoryEvent found;
  bool got = WaitFor([&] {
    std::vector<DirectoryEvent>& mine = kept[&d];
    for (auto& ev : d.TakeEvents()) mine.push_back(std::move(ev));
    for (auto it = mine.begin(); it != mine.end(); ++it) {
      if (it->room == room) {
        found = std::move(*it);
        mine.erase(it);
        return true;
      }
    }
    return false;
  });
  EXPECT_TRUE(got) << "no event for " << room;
  return found;
}

class DirectoryTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(redis_.Start()) << "redis-server did not start"; }
  RedisServer redis_;
};

TEST_F(DirectoryTest, RejectsBadOptions) {
  DirectoryOptions o = Options(redis_.port(), "a");
  o.relay_id = "bad:id";
  EXPECT_FALSE(Directory::Start(o).ok());
  o = Options(redis_.port(), "a");
  o.ttl_s = o.heartbeat_s;
  EXPECT_FALSE(Directory::Start(o).ok());
}

TEST_F(DirectoryTest, RelaysRegisterAndSeeEachOther) {
  auto a = Open(redis_.port(), "a");
  auto b = Open(redis_.port(), "b");
  a->SetLoad(3, 1, false);
  ASSERT_TRUE(WaitFor([&] {
    auto v = b->view();
    return v->healthy && v->relays.size() == 2 && v->relays.at("a").users == 3;
  }));
  EXPECT_EQ(b->view()->relays.at("a").address, "127.0.0.1:7097");
  EXPECT_GT(a->counters().heartbeats.load(), 0u);
  EXPECT_EQ(a->counters().redis_errors.load(), 0u);
}

TEST_F(DirectoryTest, ARoomHasExactlyOneOwnerAndGoesToTheLeastLoaded) {
  auto a = Open(redis_.port(), "a");
  auto b = Open(redis_.port(), "b");
  a->SetLoad(50, 5, false);
  b->SetLoad(0, 0, false);
  ASSERT_TRUE(WaitFor([&] {
    auto v = a->view();
    return v->relays.size() == 2 && v->relays.at("a").rooms == 5;
  }));
  // Both ask at once: one answer, the same for both.
  a->RequestPlacement("r1", false);
  b->RequestPlacement("r1", false);
  DirectoryEvent ea = AwaitEvent(*a, "r1");
  DirectoryEvent eb = AwaitEvent(*b, "r1");
  ASSERT_EQ(ea.kind, DirectoryEvent::Kind::kPlaced);
  ASSERT_EQ(eb.kind, DirectoryEvent::Kind::kPlaced);
  EXPECT_EQ(ea.owner, eb.owner);
  EXPECT_EQ(ea.owner, "b");  // fewer rooms
  // prefer_self does not steal an owned room.
  a->RequestPlacement("r1", true);
  EXPECT_EQ(AwaitEvent(*a, "r1").owner, "b");
  ASSERT_TRUE(WaitFor([&] {
    const RelayInfo* o = a->view()->OwnerOf("r1");
    return o != nullptr && o->id == "b";
  }));
  // Release by a non-owner is a no-op; by the owner it frees the room.
  a->Release("r1");
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_NE(b->view()->OwnerOf("r1"), nullptr);
  b->Release("r1");
  ASSERT_TRUE(WaitFor([&] { return b->view()->OwnerOf("r1") == nullptr; }));
}

TEST_F(DirectoryTest, ADeadRelaysRoomsAreClaimedOnceWithTheirSnapshot) {
  auto a = Open(redis_.port(), "a");
  auto b = Open(redis_.port(), "b");
  auto c = Open(redis_.port(), "c");
  ASSERT_TRUE(WaitFor([&] { return a->view()->relays.size() == 3; }));
  const int kRooms = 12;
  for (int i = 0; i < kRooms; ++i) {
    std::string room = "room" + std::to_string(i);
    a->RequestPlacement(room, true);
    ASSERT_EQ(AwaitEvent(*a, room).owner, "a");
    RoomSnapshot s;
    s.room = room;
    s.slots = {{7, 1}};
    EntitySnapshot e;
    e.id = kEntityIdBlock + static_cast<uint32_t>(i) + 1;
    e.owner = 7;
    e.flags = 1;
    e.state = {e.id, {static_cast<float>(i), 0, 0}, {0, 0, 0, 1}};
    s.entities.push_back(e);
    a->SaveSnapshot(room, EncodeRoomSnapshot(s));
  }
  ASSERT_TRUE(WaitFor([&] { return a->counters().snapshots_written.load() >= 1; }));
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  a.reset();  // dies (its registration is deleted on a clean stop; kill -9 waits for the TTL)
  std::map<std::string, std::string> claimed_by;
  std::map<std::string, float> restored_x;
  ASSERT_TRUE(WaitFor([&] {
    for (Directory* d : {b.get(), c.get()}) {
      for (auto& ev : d->TakeEvents()) {
        if (ev.kind != DirectoryEvent::Kind::kClaimed) continue;
        EXPECT_EQ(claimed_by.count(ev.room), 0u) << ev.room << " claimed twice";
        claimed_by[ev.room] = d->relay_id();
        EXPECT_TRUE(ev.has_snapshot);
        if (ev.has_snapshot && ev.snapshot.entities.size() == 1) {
          restored_x[ev.room] = ev.snapshot.entities[0].state.position.x;
        }
      }
    }
    return claimed_by.size() == kRooms;
  }));
  std::this_thread::sleep_for(std::chrono::milliseconds(300));  // no late double claims
  for (Directory* d : {b.get(), c.get()}) {
    for (auto& ev : d->TakeEvents()) EXPECT_NE(ev.kind, DirectoryEvent::Kind::kClaimed);
  }
  for (int i = 0; i < kRooms; ++i) {
    EXPECT_FLOAT_EQ(restored_x["room" + std::to_string(i)], static_cast<float>(i));
  }
  // Spread over both survivors.
  int on_b = 0;
  for (auto& [room, id] : claimed_by) on_b += id == "b";
  EXPECT_GT(on_b, 0);
  EXPECT_LT(on_b, kRooms);
  EXPECT_EQ(b->counters().claims.load() + c->counters().claims.load(),
            static_cast<uint64_t>(kRooms));
}

TEST_F(DirectoryTest, GarbageInKeysIsCountedNotFatal) {
  RedisClient raw("127.0.0.1", redis_.port(), 1.0);
  // A relay registration that is not JSON, one that is JSON of the wrong shape, a room whose
  // key is a hash (WRONGTYPE), a room owned by an unknown relay with a snapshot of noise.
  ASSERT_TRUE(raw.Command({"SADD", "edgephys:relays", "junk", "shape", "bin"}).ok());
  ASSERT_TRUE(raw.Command({"SET", "edgephys:relay:junk", "{not json", "PX", "60000"}).ok());
  ASSERT_TRUE(raw.Command({"SET", "edgephys:relay:shape", "[1,2,3]", "PX", "60000"}).ok());
  ASSERT_TRUE(
      raw.Command({"SET", "edgephys:relay:bin", std::string("\0\xff\x01", 3), "PX", "60000"})
          .ok());
  ASSERT_TRUE(raw.Command({"HSET", "edgephys:room:hashroom", "f", "v"}).ok());
  ASSERT_TRUE(raw.Command({"SADD", "edgephys:rooms", "hashroom", "orphan"}).ok());
  ASSERT_TRUE(raw.Command({"SET", "edgephys:room:orphan", "ghost"}).ok());
  ASSERT_TRUE(raw.Command({"SET", "edgephys:state:orphan", "EPRS\x01garbage"}).ok());
  auto a = Open(redis_.port(), "a");
  a->RequestPlacement("hashroom", false);
  DirectoryEvent ev = AwaitEvent(*a, "hashroom");
  // A room key of the wrong type is garbage: the placement replaces it.
  EXPECT_EQ(ev.kind, DirectoryEvent::Kind::kPlaced);
  EXPECT_EQ(ev.owner, "a");
  // The orphan (owner "ghost" is not live) is claimed; its snapshot is garbage: no snapshot.
  DirectoryEvent claimed = AwaitEvent(*a, "orphan");
  EXPECT_EQ(claimed.kind, DirectoryEvent::Kind::kClaimed);
  EXPECT_FALSE(claimed.has_snapshot);
  EXPECT_GE(a->counters().bad_keys.load(), 4u);
  auto v = a->view();
  EXPECT_TRUE(v->healthy);
  EXPECT_EQ(v->relays.size(), 1u);  // only "a" is a valid live relay
  // The garbage entries' keys live: alive but unroutable, not dead.
  EXPECT_EQ(v->unroutable.size(), 3u);
  // The relays set itself of the wrong type: counted, the directory keeps running.
  ASSERT_TRUE(raw.Command({"DEL", "edgephys:relays"}).ok());
  ASSERT_TRUE(raw.Command({"SET", "edgephys:relays", "oops"}).ok());
  uint64_t before = a->counters().bad_keys.load();
  ASSERT_TRUE(WaitFor([&] { return a->counters().bad_keys.load() > before; }));
}

// One anomaly in Redis never makes a live relay dead: its room is not claimed while its own
// heartbeat key lives, whatever the relay set or its entry say; an entry with an unusable
// address is never placed on.
TEST_F(DirectoryTest, AnomaliesNeverMakeALiveRelayDead) {
  RedisClient raw("127.0.0.1", redis_.port(), 1.0);
  auto a = Open(redis_.port(), "a");
  auto b = Open(redis_.port(), "b");
  ASSERT_TRUE(WaitFor([&] { return b->view()->relays.size() == 2; }));
  a->RequestPlacement("r", true);
  ASSERT_EQ(AwaitEvent(*a, "r").owner, "a");
  auto no_claim_for = [&](double seconds) {
    const auto end = std::chrono::steady_clock::now() + std::chrono::duration<double>(seconds);
    while (std::chrono::steady_clock::now() < end) {
      for (auto& ev : b->TakeEvents()) {
        if (ev.kind == DirectoryEvent::Kind::kClaimed) return false;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return b->counters().claims.load() == 0;
  };
  // a missing from the relay set (until its next heartbeat re-adds it).
  ASSERT_TRUE(raw.Command({"SREM", "edgephys:relays", "a"}).ok());
  EXPECT_TRUE(no_claim_for(0.6));
  // a's entry overwritten with garbage (its next heartbeat repairs it).
  ASSERT_TRUE(raw.Command({"SET", "edgephys:relay:a", "{garbage", "PX", "60000"}).ok());
  EXPECT_TRUE(no_claim_for(0.6));
  // The relay set of the wrong type.
  ASSERT_TRUE(raw.Command({"DEL", "edgephys:relays"}).ok());
  ASSERT_TRUE(raw.Command({"HSET", "edgephys:relays", "f", "v"}).ok());
  EXPECT_TRUE(no_claim_for(0.6));
  ASSERT_TRUE(raw.Command({"DEL", "edgephys:relays"}).ok());
  EXPECT_EQ(a->view()->room_owner.at("r"), "a");
  // A relay whose entry has an unparseable address: alive, never a placement target (it
  // would be the least loaded).
  ASSERT_TRUE(raw.Command({"SADD", "edgephys:relays", "bad"}).ok());
  ASSERT_TRUE(raw.Command({"SET", "edgephys:relay:bad",
                           R"({"address":"not an address","users":0,"rooms":0})", "PX", "60000"})
                  .ok());
  ASSERT_TRUE(WaitFor([&] { return b->view()->unroutable.count("bad") == 1; }));
  for (int i = 0; i < 4; ++i) {
    const std::string room = "spread" + std::to_string(i);
    b->RequestPlacement(room, false);
    DirectoryEvent ev = AwaitEvent(*b, room);
    EXPECT_EQ(ev.kind, DirectoryEvent::Kind::kPlaced);
    EXPECT_NE(ev.owner, "bad");
  }
}

TEST_F(DirectoryTest, RedisDownIsCountedAndTheViewTurnsUnhealthy) {
  auto a = Open(redis_.port(), "a");
  ASSERT_TRUE(WaitFor([&] { return a->view()->healthy; }));
  redis_.Stop();
  ASSERT_TRUE(WaitFor([&] { return !a->view()->healthy; }, 5.0));
  EXPECT_GT(a->counters().redis_errors.load(), 0u);
  a->RequestPlacement("r", false);
  EXPECT_EQ(AwaitEvent(*a, "r").kind, DirectoryEvent::Kind::kPlacementFailed);
  // Public calls never block on Redis: a burst returns at once.
  auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < 1000; ++i) {
    a->SaveSnapshot("r" + std::to_string(i % 10), {1, 2, 3});
    a->SetLoad(1, 1, false);
    (void)a->view();
    (void)a->TakeEvents();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(1));
}

}  // namespace
}  // namespace edgephys::cluster
