// Relays in a cluster over a real redis-server (free loopback port), in one process on real
// loopback UDP: placement, signed redirects followed by the SDK, failover with restored rooms
// and resumed sessions, forged/expired redirects refused, garbage snapshots survived.
#include "relay/cluster_hook.h"

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <map>
#include <set>
#include <thread>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "client/client_testing.h"
#include "cluster/redis_client.h"
#include "cluster/testing/redis_server.h"
#include "protocol/container_builder.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/redirect.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"
#include "relay/testing/cluster_world.h"
#include "tests/integration/harness.h"

namespace edgephys {
namespace {

constexpr char kSecret[] = "cluster-secret";
constexpr uint32_t kPersistent = static_cast<uint32_t>(schema::EntityFlags::Persistent);

using testing::UnixNow;

// A join token for `player` in `room`, valid for an hour, signed with the cluster's secret.
std::vector<uint8_t> Token(const std::string& room, uint32_t player) {
  return testing::MintToken(room, player, 3600, kDefaultPermissions, kSecret);
}

struct CountingListener : ClientListener {
  int connected = 0, joined = 0, disconnected = 0;
  void OnConnected(uint32_t) override { ++connected; }
  void OnJoined(std::string_view, uint32_t) override { ++joined; }
  void OnDisconnected(DisconnectReason) override { ++disconnected; }
};

// N relays (each its own UDP socket and Relay) and clients, pumped from the test thread.
class ClusterWorld : public testing::Pumped<ClusterWorld> {
 public:
  ClusterWorld(uint16_t redis_port, int relays) {
    for (int i = 0; i < relays; ++i) AddRelay(redis_port, "r" + std::to_string(i));
  }

  void AddRelay(uint16_t redis_port, const std::string& id) {
    const int i = nodes_.AddNode();
    nodes_.StartRelay(i, testing::ClusterNodes::Config(kSecret), redis_port, id, 0.1);
  }

  double Now() const { return clock_.Now(); }

  Client& AddClient(int via, const std::vector<uint8_t>& token, CountingListener* listener) {
    return clients_.Add(nodes_.ResumingClientConfig(), listener, ToRelayAddress(endpoint(via)),
                        token, Now());
  }

  void Step() {
    double now = Now();
    nodes_.Update(now);
    // The game: join once connected (the SDK rejoins by itself after a failover).
    clients_.Update(now, [this](Client* c) { return rooms_[c]; });
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  void set_room(Client& c, const std::string& room) { rooms_[&c] = room; }

  // One player per listener: player first_player + i joins room "<prefix><i % rooms>" through
  // relay i % size().
  std::vector<Client*> AddPlayers(const std::string& prefix, int rooms, uint32_t first_player,
                                  std::vector<CountingListener>* listeners) {
    std::vector<Client*> clients;
    for (size_t i = 0; i < listeners->size(); ++i) {
      const std::string room = prefix + std::to_string(i % rooms);
      Client& c = AddClient(static_cast<int>(i % size()),
                            Token(room, first_player + static_cast<uint32_t>(i)), &(*listeners)[i]);
      set_room(c, room);
      clients.push_back(&c);
    }
    return clients;
  }

  // Destroys relay `i` (its UDP port goes silent; clean directory stop).
  void Kill(int i) { nodes_.Kill(i); }
  Relay* relay(int i) { return nodes_.relay(i); }
  const RelayCounters& counters(int i) const { return nodes_.counters(i); }
  Endpoint endpoint(int i) const { return nodes_.endpoint(i); }
  int size() const { return nodes_.size(); }
  // Index of the live relay holding `room`, -1 if none.
  int Holder(const std::string& room) {
    for (int i = 0; i < size(); ++i) {
      if (relay(i) != nullptr && relay(i)->FindRoom(room) != nullptr) return i;
    }
    return -1;
  }

 private:
  testing::WallClock clock_;
  testing::ClusterNodes nodes_;
  testing::AutoJoiningClients clients_;
  std::map<Client*, std::string> rooms_;
};

class ClusterTest : public ::testing::Test {
 protected:
  void SetUp() override { ASSERT_TRUE(redis_.Start()) << "redis-server did not start"; }

  // The start of the tests of a room that outlives its relay: three relays register; a (player
  // `first`, through relay 0) and b (`first + 1`, through relay 1) join `room`; a spawns a
  // persistent entity (tool_) and b sees it. Fails the test (fatally) at the first step that
  // does not finish.
  void StartPairWithTool(const char* room, uint32_t first) {
    world_ = std::make_unique<ClusterWorld>(redis_.port(), 3);
    world_->RunUntil([] { return false; }, 0.3);
    a_ = &world_->AddClient(0, Token(room, first), &la_);
    b_ = &world_->AddClient(1, Token(room, first + 1), &lb_);
    world_->set_room(*a_, room);
    world_->set_room(*b_, room);
    ASSERT_TRUE(world_->RunUntil([&] { return a_->joined() && b_->joined(); }, 15.0));
    SpawnDesc d;
    d.flags = kPersistent;
    auto spawned = a_->Spawn(d);
    ASSERT_TRUE(spawned.ok());
    tool_ = *spawned;
    ASSERT_TRUE(world_->RunUntil([&] { return b_->FindEntity(tool_) != nullptr; }, 5.0));
  }

  // Lets a snapshot be written (a snapshot interval or more), kills the relay holding `room`,
  // and pumps (5 s at most) until another relay holds the room and `restored` (if given) is
  // true of its host there. Fails the test (fatally) at the first step that does not finish.
  void KillTheRoomsRelay(const std::string& room,
                         const std::function<bool(const RoomHost&)>& restored = nullptr) {
    ClusterWorld& world = *world_;
    world.RunUntil([] { return false; }, 0.4);
    const int victim = world.Holder(room);
    ASSERT_GE(victim, 0);
    world.Kill(victim);
    ASSERT_TRUE(world.RunUntil([&] {
      const int h = world.Holder(room);
      return h >= 0 && world.relay(h)->rooms().count(room) != 0 &&
             (!restored || restored(*world.relay(h)->rooms().at(room)));
    }, 5.0));
  }

  cluster::testing::RedisServer redis_;
  // StartPairWithTool's (the listeners outlive the world's clients).
  CountingListener la_, lb_;
  std::unique_ptr<ClusterWorld> world_;
  Client* a_ = nullptr;
  Client* b_ = nullptr;
  uint32_t tool_ = 0;
};

TEST_F(ClusterTest, PlayersJoiningThroughAnyRelayLandOnTheirRoomsRelay) {
  ClusterWorld world(redis_.port(), 3);
  world.RunUntil([] { return false; }, 0.3);  // relays register
  constexpr int kRooms = 6, kPerRoom = 4;
  std::vector<CountingListener> listeners(kRooms * kPerRoom);
  const std::vector<Client*> clients = world.AddPlayers("room", kRooms, 100, &listeners);
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (Client* c : clients) {
          if (!c->joined()) return false;
        }
        return true;
      },
      15.0));
  std::set<int> holders;
  uint64_t followed = 0;
  for (int r = 0; r < kRooms; ++r) {
    std::string room = "room" + std::to_string(r);
    int holder = world.Holder(room);
    ASSERT_GE(holder, 0) << room;
    holders.insert(holder);
    EXPECT_EQ(world.relay(holder)->FindRoom(room)->size(), static_cast<size_t>(kPerRoom)) << room;
    for (int i = 0; i < world.size(); ++i) {  // nowhere else
      if (i != holder) {
        EXPECT_EQ(world.relay(i)->FindRoom(room), nullptr) << room;
      }
    }
  }
  for (size_t i = 0; i < clients.size(); ++i) {
    followed += clients[i]->redirects_followed();
    EXPECT_EQ(clients[i]->redirects_refused(), 0u);
    EXPECT_EQ(listeners[i].connected, 1);  // the redirect is invisible to the game
    EXPECT_EQ(listeners[i].joined, 1);
  }
  EXPECT_GT(followed, 0u);
  uint64_t redirects = 0;
  for (int i = 0; i < world.size(); ++i) redirects += world.counters(i).cluster_redirects.load();
  EXPECT_GE(redirects, followed);
  EXPECT_GE(holders.size(), 2u) << "rooms should spread over the relays";
}

TEST_F(ClusterTest, ADeadRelaysRoomsComeBackWithTheirEntitiesAndSessionsResume) {
  ClusterWorld world(redis_.port(), 3);
  world.RunUntil([] { return false; }, 0.3);
  constexpr int kRooms = 3, kPerRoom = 3;
  std::vector<CountingListener> listeners(kRooms * kPerRoom);
  const std::vector<Client*> clients = world.AddPlayers("fo", kRooms, 200, &listeners);
  auto all_joined = [&] {
    for (Client* c : clients) {
      if (!c->joined()) return false;
    }
    return true;
  };
  ASSERT_TRUE(world.RunUntil(all_joined, 15.0));
  // Every player spawns one persistent entity and one ordinary one.
  std::map<std::string, std::map<uint32_t, uint32_t>> owner_of;  // room -> entity -> player
  std::map<Client*, std::vector<uint32_t>> owned;
  for (Client* c : clients) {
    for (uint32_t flags : {kPersistent, 0u}) {
      SpawnDesc d;
      d.position = {1, 1, static_cast<float>(c->player_id() % 10)};
      d.flags = flags;
      auto id = c->Spawn(d);
      ASSERT_TRUE(id.ok());
      owner_of[c->room()][*id] = c->player_id();
      owned[c].push_back(*id);
    }
  }
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (int r = 0; r < kRooms; ++r) {
          int h = world.Holder("fo" + std::to_string(r));
          if (h < 0 || world.relay(h)->FindRoom("fo" + std::to_string(r))->entities().size() !=
                           2 * kPerRoom) {
            return false;
          }
        }
        return true;
      },
      5.0));
  world.RunUntil([] { return false; }, 0.4);  // a snapshot interval or more
  const int victim = world.Holder("fo0");
  std::vector<std::string> lost_rooms;
  for (int r = 0; r < kRooms; ++r) {
    if (world.Holder("fo" + std::to_string(r)) == victim) lost_rooms.push_back("fo" + std::to_string(r));
  }
  std::map<Client*, uint32_t> base_before;
  for (Client* c : clients) base_before[c] = c->entity_id_base();
  world.Kill(victim);
  // Rooms back elsewhere, with every entity, its owner intact.
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (const auto& room : lost_rooms) {
          int h = world.Holder(room);
          if (h < 0 || world.relay(h)->FindRoom(room)->entities().size() != 2 * kPerRoom) {
            return false;
          }
        }
        return true;
      },
      5.0));
  for (const auto& room : lost_rooms) {
    const Room* restored = world.relay(world.Holder(room))->FindRoom(room);
    ASSERT_EQ(restored->entities().size(), owner_of[room].size());
    for (const auto& [id, e] : restored->entities()) {
      ASSERT_EQ(owner_of[room].count(id), 1u) << id;
      EXPECT_EQ(e.owner, owner_of[room][id]) << id;
    }
  }
  // Every player of a lost room resumes there with its id block; nobody saw a disconnect or a
  // second join.
  auto resumes = [&] {
    uint64_t n = 0;
    for (Client* c : clients) n += c->resumes();
    return n;
  };
  const uint64_t expected_resumes = lost_rooms.size() * kPerRoom;
  ASSERT_TRUE(world.RunUntil([&] { return resumes() >= expected_resumes && all_joined(); }, 10.0))
      << resumes();
  for (size_t i = 0; i < clients.size(); ++i) {
    Client* c = clients[i];
    EXPECT_EQ(c->entity_id_base(), base_before[c]);
    EXPECT_EQ(listeners[i].disconnected, 0);
    EXPECT_EQ(listeners[i].joined, 1);
  }
  EXPECT_EQ(resumes(), expected_resumes);
  // They publish again, and the room sees it: move every entity.
  const Vec3f moved{3, 2, 1};
  ASSERT_TRUE(world.RunUntil(
      [&] {
        for (auto& [c, ids] : owned) {
          for (uint32_t id : ids) (void)c->PublishTransform(id, moved, Quatf{});
        }
        for (const auto& room : lost_rooms) {
          int h = world.Holder(room);
          for (const auto& [id, e] : world.relay(h)->FindRoom(room)->entities()) {
            if (std::abs(e.state.position.x - moved.x) > 0.01f) return false;
          }
        }
        return true;
      },
      5.0));
  const auto* hook = world.relay(world.Holder(lost_rooms[0]))->cluster();
  ASSERT_NE(hook, nullptr);
  EXPECT_GE(hook->counters().rooms_restored, 1u);
  EXPECT_EQ(hook->counters().entities_skipped, 0u);
}

// Room and entity properties survive the death of their room's relay: the snapshot carries
// them, the relay that claims the room restores them (values, versions, writers, authority),
// the resumed members are told them again, and compare-and-set goes on from the same versions.
TEST_F(ClusterTest, PropertiesComeBackWithTheRoomAfterItsRelayDies) {
  ASSERT_NO_FATAL_FAILURE(StartPairWithTool("pr", 301));
  ClusterWorld& world = *world_;
  Client &a = *a_, &b = *b_;
  const uint32_t tool = tool_;
  ASSERT_TRUE(a.CompareAndSetProperty(0, "step", PropertyValue::Int64(1), 0,
                                      PropertyAuthority::kAnyone).ok());
  ASSERT_TRUE(a.SetProperty(tool, "tip", PropertyValue::Vec3({1, 2, 3})).ok());
  ASSERT_TRUE(b.SetProperty(0, "title", PropertyValue::String("suture")).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    const PropertyRecord* step = b.FindProperty(0, "step");
    return step != nullptr && step->version == 1 && b.properties().size() == 3 &&
           a.properties().size() == 3;
  }, 5.0));
  ASSERT_TRUE(b.CompareAndSetProperty(0, "step", PropertyValue::Int64(2), 1).ok());
  ASSERT_TRUE(world.RunUntil([&] { return a.FindProperty(0, "step")->version == 2; }, 5.0));
  const std::map<PropertyKey, PropertyRecord> before = a.properties();
  ASSERT_NO_FATAL_FAILURE(KillTheRoomsRelay(
      "pr", [](const RoomHost& restored) { return restored.properties().count() == 3; }));
  const RoomHost& host = *world.relay(world.Holder("pr"))->rooms().at("pr");
  for (const auto& [k, want] : before) {
    const StoredProperty* got = host.properties().Find(k.first, k.second);
    ASSERT_NE(got, nullptr) << k.second;
    EXPECT_EQ(got->value, want.value) << k.second;
    EXPECT_EQ(got->version, want.version) << k.second;
    EXPECT_EQ(got->writer, want.writer) << k.second;
    EXPECT_EQ(got->authority, want.authority) << k.second;
  }
  // The members resume and are told every property again, as it was.
  ASSERT_TRUE(world.RunUntil([&] {
    return a.resumes() + b.resumes() >= 2 && a.joined() && b.joined() &&
           a.properties().size() == 3 && b.properties().size() == 3;
  }, 10.0));
  for (const Client* c : {&a, &b}) {
    for (const auto& [k, want] : before) {
      const PropertyRecord* got = c->FindProperty(k.first, k.second);
      ASSERT_NE(got, nullptr) << k.second;
      EXPECT_EQ(got->value, want.value);
      EXPECT_EQ(got->version, want.version);
    }
  }
  // Compare-and-set goes on from the restored version; an outdated one loses.
  ASSERT_TRUE(a.CompareAndSetProperty(0, "step", PropertyValue::Int64(3), 2).ok());
  ASSERT_TRUE(b.CompareAndSetProperty(0, "step", PropertyValue::Int64(9), 1).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    const PropertyRecord* step = b.FindProperty(0, "step");
    return step != nullptr && step->version == 3;
  }, 5.0));
  EXPECT_EQ(b.FindProperty(0, "step")->value, PropertyValue::Int64(3));
  EXPECT_EQ(host.property_stats().conflicts, 1u);
}

// Ownership survives the death of the room's relay: the restored entity keeps its owner,
// authority sequence, former owner, takeover setting and leave choice, so the former owner's
// late states are still dropped and counted as stale, and the owner's are taken.
TEST_F(ClusterTest, OwnershipComesBackWithTheRoomAndStaleStatesStayStale) {
  ASSERT_NO_FATAL_FAILURE(StartPairWithTool("ow", 311));
  ClusterWorld& world = *world_;
  Client &a = *a_, &b = *b_;
  const uint32_t tool = tool_;
  ASSERT_TRUE(a.HandOver(tool, 312).ok());
  ASSERT_TRUE(world.RunUntil([&] { return b.Owns(tool); }, 5.0));
  ASSERT_TRUE(b.SetTakeoverAllowed(tool, true).ok());
  ASSERT_TRUE(b.SetOwnerLeave(tool, 2).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    const auto& entities = world.relay(world.Holder("ow"))->FindRoom("ow")->entities();
    const auto it = entities.find(tool);
    return it != entities.end() && it->second.takeover_allowed && it->second.on_owner_leave == 2;
  }, 5.0));
  ASSERT_NO_FATAL_FAILURE(KillTheRoomsRelay("ow"));
  const RoomHost& host = *world.relay(world.Holder("ow"))->rooms().at("ow");
  const Entity* e = host.room().entities().count(tool) ? &host.room().entities().at(tool) : nullptr;
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->owner, 312u);
  EXPECT_EQ(e->authority_seq, 1u);
  EXPECT_EQ(e->former_owner, 311u);
  EXPECT_TRUE(e->takeover_allowed);
  EXPECT_EQ(e->on_owner_leave, 2);
  ASSERT_TRUE(world.RunUntil([&] { return a.resumes() + b.resumes() >= 2 && a.joined() && b.joined(); }, 10.0));
  // A, the former owner, sends a late state: dropped and counted; B's next one is taken.
  ASSERT_TRUE(ClientTesting::SendStateUnchecked(a, {tool, {42, 1, 0}, {0, 0, 0, 1}}, world.Now()).ok());
  ASSERT_TRUE(world.RunUntil([&] { return host.ownership_stats().stale == 1; }, 5.0));
  EXPECT_NE(e->state.position.x, 42.f);
  ASSERT_TRUE(b.PublishTransform(tool, {-3, 1, 0}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(world.RunUntil([&] { return e->state.position.x == -3.f; }, 5.0));
}

// The room's owner key is overwritten with an unknown relay id while its holder is healthy:
// the holder takes the lease back at its next refresh and keeps its live copy (the other relay
// waits a refresh longer before claiming an ownerless room, so it never restores a second,
// older copy). A newcomer through the other relay lands in the one copy; the members are never
// disconnected; every entity exists once.
TEST_F(ClusterTest, ACorruptedLeaseIsTakenBackByTheLiveHolder) {
  ClusterWorld world(redis_.port(), 2);
  world.RunUntil([] { return false; }, 0.3);
  std::vector<CountingListener> listeners(3);
  std::vector<Client*> members;
  for (int i = 0; i < 2; ++i) {
    Client& c = world.AddClient(i, Token("split", 300 + i), &listeners[i]);
    world.set_room(c, "split");
    members.push_back(&c);
  }
  auto joined = [](const std::vector<Client*>& cs) {
    for (Client* c : cs) {
      if (!c->joined()) return false;
    }
    return true;
  };
  ASSERT_TRUE(world.RunUntil([&] { return joined(members); }, 15.0));
  for (Client* c : members) {
    SpawnDesc d;
    d.flags = kPersistent;
    d.position = {1, 2, static_cast<float>(c->player_id() % 10)};
    ASSERT_TRUE(c->Spawn(d).ok());
  }
  const int holder = world.Holder("split");
  ASSERT_GE(holder, 0);
  const int other = 1 - holder;
  ASSERT_TRUE(world.RunUntil(
      [&] { return world.relay(holder)->FindRoom("split")->entities().size() == 2; }, 5.0));
  world.RunUntil([] { return false; }, 0.4);  // a snapshot is written
  cluster::RedisClient raw("127.0.0.1", redis_.port(), 1.0);
  ASSERT_TRUE(raw.Command({"SET", "edgephys:room:split", "ghost"}).ok());
  ASSERT_TRUE(world.RunUntil([&] { return world.Holder("split") == holder; }, 5.0));
  Client& late = world.AddClient(other, Token("split", 399), &listeners[2]);
  world.set_room(late, "split");
  members.push_back(&late);
  ASSERT_TRUE(world.RunUntil([&] {
    const Room* room = world.relay(holder)->FindRoom("split");
    return room != nullptr && room->members().size() == 3 && joined(members);
  }, 10.0));
  world.RunUntil([] { return false; }, 1.0);
  EXPECT_EQ(world.relay(other)->FindRoom("split"), nullptr);  // never a second copy
  EXPECT_EQ(world.relay(other)->cluster()->counters().rooms_restored, 0u);
  EXPECT_EQ(world.relay(holder)->cluster()->counters().rooms_handed_over, 0u);
  EXPECT_EQ(world.relay(holder)->FindRoom("split")->entities().size(), 2u);  // the live copy
  EXPECT_EQ(world.Holder("split"), holder);
  for (int i = 0; i < 2; ++i) {
    EXPECT_EQ(listeners[i].disconnected, 0);
    EXPECT_EQ(listeners[i].joined, 1);
  }
}

TEST_F(ClusterTest, GarbageSnapshotsAreCountedAndTheRoomStillComesBack) {
  ClusterWorld world(redis_.port(), 1);
  cluster::RedisClient raw("127.0.0.1", redis_.port(), 1.0);
  // A room owned by a relay that is gone, whose snapshot decodes but holds an entity whose
  // stored spawn is junk, and another whose snapshot is noise.
  cluster::RoomSnapshot s;
  s.room = "junk";
  cluster::EntitySnapshot e;
  e.id = kEntityIdBlock + 1;
  e.owner = 5;
  e.spawn = {1, 2, 3, 4, 5, 6, 7, 8, 9};
  s.entities.push_back(e);
  auto bytes = cluster::EncodeRoomSnapshot(s);
  ASSERT_TRUE(raw.Command({"SET", "edgephys:room:junk", "ghost"}).ok());
  ASSERT_TRUE(raw.Command({"SET", "edgephys:room:noise", "ghost"}).ok());
  ASSERT_TRUE(
      raw.Command({"SET", "edgephys:state:junk", std::string(bytes.begin(), bytes.end())}).ok());
  ASSERT_TRUE(raw.Command({"HSET", "edgephys:state:noise", "x", "y"}).ok());
  // Last (a room listed before its key exists is dropped from the list by a refresh).
  ASSERT_TRUE(raw.Command({"SADD", "edgephys:rooms", "junk", "noise"}).ok());
  ASSERT_TRUE(world.RunUntil(
      [&] { return world.relay(0)->FindRoom("junk") && world.relay(0)->FindRoom("noise"); }, 5.0));
  EXPECT_TRUE(world.relay(0)->FindRoom("junk")->entities().empty());
  EXPECT_EQ(world.relay(0)->cluster()->counters().entities_skipped, 1u);
  EXPECT_GE(world.relay(0)->cluster()->directory().counters().bad_keys.load(), 1u);
  world.Step();  // publishes the counters (edgephys_cluster_*_total)
  EXPECT_GE(world.counters(0).cluster_bad_keys.load(), 2u);
  EXPECT_EQ(world.counters(0).cluster_rooms_restored.load(), 2u);
  // And the relay still serves: a player joins the restored room.
  CountingListener l;
  Client& c = world.AddClient(0, Token("junk", 9), &l);
  world.set_room(c, "junk");
  EXPECT_TRUE(world.RunUntil([&] { return c.joined(); }, 5.0));
}

// A fake relay: answers Hello with a Challenge, and Connect with `reply`.
class FakeRelay {
 public:
  FakeRelay() : socket_(std::move(*UdpSocket::Open(*ParseEndpoint("127.0.0.1:0")))) {}
  Endpoint endpoint() const { return socket_->LocalEndpoint(); }
  // Handles what arrived; returns the token of a Connect, if one came.
  void Pump(const std::function<std::vector<uint8_t>()>& reply) {
    std::vector<uint8_t> buf(2048);
    Endpoint from;
    for (size_t n; (n = socket_->ReceiveFrom(&from, buf)) > 0;) {
      PacketPrefix prefix{};
      DropReason reason{};
      if (!ParsePacketPrefix({buf.data(), n}, &prefix, &reason)) continue;
      flatbuffers::FlatBufferBuilder fbb;
      if (prefix.type == PacketType::kHello) {
        std::vector<uint8_t> cookie(kCookieSize, 7);
        FinishControl(fbb, schema::CreateChallenge(fbb, fbb.CreateVector(cookie)));
        (void)socket_->SendTo(from, BuildHandshakePacket(PacketType::kChallenge, fbb));
      } else if (prefix.type == PacketType::kConnect) {
        ++connects;
        (void)socket_->SendTo(from, reply());
      }
    }
  }
  int connects = 0;

 private:
  std::unique_ptr<UdpSocket> socket_;
};

TEST(ClusterRedirect, ForgedAndExpiredRedirectsAreRefusedByTheSdk) {
  FakeRelay fake;
  FakeRelay target;
  auto token = Token("arena", 7);
  auto udp = std::move(*UdpSocket::Open(*ParseEndpoint("127.0.0.1:0")));
  Client client(ClientConfig{}, udp.get());
  auto start = std::chrono::steady_clock::now();
  auto now = [&] {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  };
  ASSERT_TRUE(client.Connect(ToRelayAddress(fake.endpoint()), token, now()).ok());
  const std::string target_address = FormatEndpoint(target.endpoint());
  std::vector<std::function<std::vector<uint8_t>()>> replies = {
      // Signed with another token (an attacker who does not hold this one).
      [&] { return BuildRedirectPacket(*SignRedirect(testing::RelayPart(Token("arena", 7)), testing::SecretOf(Token("arena", 7)), target_address, UnixNow() + 30)); },
      // Right token, tampered address.
      [&] {
        auto t = *SignRedirect(testing::RelayPart(token), testing::SecretOf(token), target_address, UnixNow() + 30);
        t.address = "127.0.0.1:9";
        return BuildRedirectPacket(t);
      },
      // Right token, expired.
      [&] { return BuildRedirectPacket(*SignRedirect(testing::RelayPart(token), testing::SecretOf(token), target_address, UnixNow() - 1)); },
  };
  for (size_t i = 0; i < replies.size(); ++i) {
    const int connects_before = fake.connects;
    for (int k = 0; k < 400 && client.redirects_refused() == i; ++k) {
      fake.Pump(replies[i]);
      client.Update(now());
      std::this_thread::sleep_for(std::chrono::milliseconds(2));
    }
    EXPECT_EQ(client.redirects_refused(), i + 1) << i;
    EXPECT_GT(fake.connects, connects_before);
    EXPECT_EQ(client.redirects_followed(), 0u);
    EXPECT_EQ(client.server(), ToRelayAddress(fake.endpoint()));
    EXPECT_EQ(client.state(), ClientState::kHandshaking);
  }
  // A genuine one is followed: the handshake moves to the target.
  for (int k = 0; k < 400 && target.connects == 0; ++k) {
    fake.Pump([&] { return BuildRedirectPacket(*SignRedirect(testing::RelayPart(token), testing::SecretOf(token), target_address, UnixNow() + 30)); });
    target.Pump([&] { return std::vector<uint8_t>{}; });
    client.Update(now());
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_EQ(client.redirects_followed(), 1u);
  EXPECT_EQ(client.server(), ToRelayAddress(target.endpoint()));
  EXPECT_GT(target.connects, 0);
}

}  // namespace
}  // namespace edgephys
