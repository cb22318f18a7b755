// The replication scheduler: send rates by priority class, selective synchronisation, the
// bandwidth budget's fairness, and the emulation modes, through the real relay and SDK.
#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "loadgen/emulation/emulation_plugins.h"
#include "tests/integration/sim_world.h"

namespace edgephys::testing {
namespace {

struct Counter : ClientListener {
  std::map<uint32_t, int> updates;
  void OnEntityUpdated(const RemoteEntity& e) override { ++updates[e.id]; }
};

struct Room2 {
  SimWorld world;
  Counter counter;
  Client* a;
  Client* b;
  explicit Room2(const ReplicationConfig& replication, NetworkConditions net = {},
                 bool decode_emulations = true)
      : world(net, Config(replication)) {
    ClientConfig receiver;  // decodes the emulations' formats (loadgen/emulation/)
    if (decode_emulations) receiver.state_decoder = EmulationStateDecoder();
    a = &world.AddClient(MintToken("rep", 1));
    b = &world.AddClient(MintToken("rep", 2), &counter, receiver);
    EXPECT_TRUE(world.RunUntil([&] {
      return a->state() == ClientState::kConnected && b->state() == ClientState::kConnected;
    }, 5.0));
    EXPECT_TRUE(a->JoinRoom("rep").ok());
    EXPECT_TRUE(b->JoinRoom("rep").ok());
    EXPECT_TRUE(world.RunUntil([&] { return a->joined() && b->joined(); }, 5.0));
  }
  static RelayConfig Config(const ReplicationConfig& replication) {
    RelayConfig c = LoopbackWorld::DefaultConfig();
    c.room_defaults.tick_rate_hz = 60;
    c.room_defaults.replication = replication;
    // The fake clock runs far ahead of real time: PhyS must step in the same update
    // (synchronously, one thread) for the rates measured on it to be deterministic.
    c.physics_threads = 1;
    return c;
  }
  // A moves every entity in `ids` at `hz` for `seconds`.
  void Move(const std::vector<uint32_t>& ids, double hz, double seconds) {
    double next = world.Now();
    world.RunFor(seconds, [&](double now) {
      if (now < next) return;
      next += 1.0 / hz;
      for (uint32_t id : ids) {
        float t = static_cast<float>(now);
        ASSERT_TRUE(a->PublishTransform(id, {t, std::sin(t), float(id % 7)},
                                        {0, std::sin(t / 2), 0, std::cos(t / 2)}).ok());
      }
    });
  }
};

TEST(Replication, CriticalEntitiesGoAt48HzNormalAt12HzRestingOnlyOnChange) {
  ReplicationConfig r;
  UseReplicationMode(ReplicationMode::kFloat, &r);
  Room2 room(r);
  auto hand = *room.a->Spawn({.flags = 1u << 4 /* Hand */});
  auto cube = *room.a->Spawn({});
  auto still = *room.a->Spawn({});
  room.world.RunFor(0.5);
  room.counter.updates.clear();
  room.Move({hand, cube}, 120, 3.0);  // the owner publishes faster than either class rate
  // The SDK publishes at 30 Hz, so a hand cannot exceed 30 updates/s end to end; the relay
  // forwards it at min(48, 30) and the cube at 12.
  EXPECT_NEAR(room.counter.updates[cube] / 3.0, 12.0, 12.0 * 0.15);
  EXPECT_NEAR(room.counter.updates[hand] / 3.0, 30.0, 30.0 * 0.15);
  EXPECT_EQ(room.counter.updates[still], 0);  // resting: unchanged, never re-sent
}

TEST(Replication, PriorityAccumulatorSendsEveryEntityUnderATooSmallBudget) {
  ReplicationConfig r;
  UseReplicationMode(ReplicationMode::kFloat, &r);
  r.bandwidth_budget_bytes_per_s = 3000;  // ~90 updates/s of 33 bytes; 40 entities want 480/s
  Room2 room(r);
  std::vector<uint32_t> ids;
  for (int i = 0; i < 40; ++i) ids.push_back(*room.a->Spawn({}));
  room.world.RunFor(0.5);
  room.counter.updates.clear();
  uint64_t bytes_before = room.b->stats()->bytes_received;
  room.Move(ids, 12, 6.0);
  uint64_t bytes = room.b->stats()->bytes_received - bytes_before;
  // The budget holds (with the keep-alive/ack packets on top).
  EXPECT_LT(static_cast<double>(bytes) / 6.0, 3000 * 1.25);
  // Nothing starves: every entity was updated, and fairly.
  int min_updates = 1 << 30, max_updates = 0;
  for (uint32_t id : ids) {
    min_updates = std::min(min_updates, room.counter.updates[id]);
    max_updates = std::max(max_updates, room.counter.updates[id]);
  }
  double mean = 0;
  for (uint32_t id : ids) mean += room.counter.updates[id];
  mean /= static_cast<double>(ids.size());
  // The budget is used (counted on the wire, sealed: ~55 B per update at this budget, one
  // update a datagram at most ticks), and spread over every entity.
  EXPECT_GT(static_cast<double>(bytes) / 6.0, 3000 * 0.6);
  EXPECT_GT(mean, 5.0);
  EXPECT_GE(min_updates, 5);
  EXPECT_LE(max_updates, 3 * min_updates) << "min " << min_updates << " mean " << mean;
}

TEST(Replication, EmulationModesDeliverExactStates) {
  for (ReplicationMode mode : {ReplicationMode::kPhoton, ReplicationMode::kPaper}) {
    ReplicationConfig r;
    UseReplicationMode(mode, &r);
    r.fixed_rate_hz = 12;
    Room2 room(r);
    std::vector<uint32_t> ids;
    for (int i = 0; i < 70; ++i) ids.push_back(*room.a->Spawn({}));  // > 1 datagram per tick
    room.Move(ids, 12, 1.5);
    room.world.RunFor(0.5);
    const Room* relay_room = room.world.relay().FindRoom("rep");
    for (uint32_t id : ids) {
      const RemoteEntity* e = room.b->FindEntity(id);
      ASSERT_NE(e, nullptr);
      const EntityState& truth = relay_room->entities().at(id).state;
      EXPECT_EQ(e->state.position.x, truth.position.x) << ReplicationModeName(mode);
      EXPECT_EQ(e->state.rotation.y, truth.rotation.y) << ReplicationModeName(mode);
    }
    EXPECT_NEAR(room.counter.updates[ids[0]] / 2.0, 12.0, 3.0) << ReplicationModeName(mode);
  }
}

// The SDK decodes formats 9, 2 and 11 only: a relay sending an emulation's format to a client
// without the matching decoder gets every payload refused and counted, nothing applied.
TEST(Replication, FormatsTheSdkDoesNotCarryAreRefusedAndCounted) {
  for (ReplicationMode mode :
       {ReplicationMode::kFloat, ReplicationMode::kPhoton, ReplicationMode::kPaper}) {
    ReplicationConfig r;
    UseReplicationMode(mode, &r);
    r.fixed_rate_hz = 12;
    Room2 room(r, {}, /*decode_emulations=*/false);
    EXPECT_EQ(room.b->state_format(), ReplicationPluginFor(mode)->state_format());
    auto id = *room.a->Spawn({});
    room.Move({id}, 12, 1.0);
    room.world.RunFor(0.3);
    EXPECT_GT(room.b->state_payloads_refused(), 5u) << ReplicationModeName(mode);
    EXPECT_EQ(room.counter.updates[id], 0) << ReplicationModeName(mode);
    EXPECT_EQ(room.b->state(), ClientState::kConnected) << ReplicationModeName(mode);
  }
  // The product's format is decoded without any plug-in, and nothing is refused.
  Room2 room(ReplicationConfig{}, {}, /*decode_emulations=*/false);
  EXPECT_EQ(room.b->state_format(), kSharedDeltaStateFormat);
  auto id = *room.a->Spawn({});
  room.Move({id}, 12, 1.0);
  room.world.RunFor(0.3);
  EXPECT_GT(room.counter.updates[id], 5);
  EXPECT_EQ(room.b->state_payloads_refused(), 0u);
}

TEST(Replication, PaperModeSendsOnlySignificantFields) {
  ReplicationConfig r;
  UseReplicationMode(ReplicationMode::kPaper, &r);
  r.fixed_rate_hz = 12;
  r.position_threshold_m = 0.01f;
  Room2 room(r);
  auto id = *room.a->Spawn({});
  room.world.RunFor(0.5);
  room.counter.updates.clear();
  // Moves below the threshold are not sent; one above it is.
  ASSERT_TRUE(room.a->PublishTransform(id, {0.004f, 0, 0}, {}).ok());
  room.world.RunFor(0.5);
  EXPECT_EQ(room.counter.updates[id], 0);
  ASSERT_TRUE(room.a->PublishTransform(id, {0.02f, 0, 0}, {}).ok());
  room.world.RunFor(0.5);
  EXPECT_EQ(room.counter.updates[id], 1);
  EXPECT_EQ(room.b->FindEntity(id)->state.position.x, 0.02f);
}

// Format 9 (ReplicationConfig::shared_encoding) through the real relay on loopback UDP, with
// the receivers' ticks on two threads: both decode every entity within the lattice bound, and
// the room's body cache served them both.
TEST(Replication, SharedEncodingOnLoopbackDeliversStatesWithinTheBound) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.tick_rate_hz = 60;
  config.room_defaults.replication.shared_encoding = true;
  config.physics_threads = 2;  // receivers' ticks in parallel: the cache is filled concurrently
  LoopbackWorld world(config);
  Client& a = world.AddClient(MintToken("shared", 1));
  Client& b = world.AddClient(MintToken("shared", 2));
  Client& c = world.AddClient(MintToken("shared", 3));
  ASSERT_TRUE(ConnectAndJoinAll(world, {&a, &b, &c}, "shared", 5.0));
  std::vector<uint32_t> ids;
  for (int i = 0; i < 30; ++i) ids.push_back(*a.Spawn({.flags = i % 3 == 0 ? 1u << 4 : 0u}));
  const double start = world.Now();
  double next = start;
  world.RunFor(2.0, [&](double now) {
    if (now < next) return;
    next += 1.0 / 60;
    for (uint32_t id : ids) {
      const float t = static_cast<float>(now - start) + 0.1f * static_cast<float>(id % 11);
      ASSERT_TRUE(a.PublishTransform(id, {1.5f * t, std::sin(t), float(id % 7) * 0.37f},
                                     {0, std::sin(t / 2), 0, std::cos(t / 2)}).ok());
    }
  });
  const Room* room = world.relay().FindRoom("shared");
  ASSERT_NE(room, nullptr);
  auto converged = [&] {
    for (Client* x : {&b, &c}) {
      for (uint32_t id : ids) {
        const RemoteEntity* e = x->FindEntity(id);
        if (e == nullptr || !e->has_state ||
            !WithinPrecision(e->state, room->entities().at(id).state)) {
          return false;
        }
      }
    }
    return true;
  };
  EXPECT_TRUE(world.RunUntil(converged, 3.0));
  ASSERT_NE(room->shared_encoding(), nullptr);
  const SharedDeltaRoomStats& st = room->shared_encoding()->stats();
  EXPECT_GT(st.encodes.load(), 0u);
  // Two receivers, one set of bodies: fewer bodies coded than updates sent.
  EXPECT_LT(st.encodes.load() + st.uncached.load(),
            world.counters().entity_updates_sent.load());
  // The relay's counters see the same: records appended from the cache and coded ones.
  EXPECT_GT(world.counters().shared_bodies_cached.load(), 0u);
  EXPECT_EQ(world.counters().shared_bodies_cached.load() +
                world.counters().shared_bodies_coded.load(),
            world.counters().entity_updates_sent.load());
}

// Format 9 on a lossy, duplicating, reordering simulated network: every receiver converges.
TEST(Replication, SharedEncodingConvergesOnALossyNetwork) {
  ReplicationConfig r;
  r.shared_encoding = true;
  const NetworkConditions net{.loss = 0.2, .duplicate = 0.1, .reorder = 0.2, .latency_s = 0.02,
                              .jitter_s = 0.01};
  Room2 room(r, net);
  std::vector<uint32_t> ids;
  for (int i = 0; i < 40; ++i) ids.push_back(*room.a->Spawn({}));
  room.Move(ids, 30, 3.0);
  const Room* relay_room = room.world.relay().FindRoom("rep");
  ASSERT_NE(relay_room, nullptr);
  EXPECT_TRUE(room.world.RunUntil([&] {
    for (uint32_t id : ids) {
      const RemoteEntity* e = room.b->FindEntity(id);
      if (e == nullptr || !WithinPrecision(e->state, relay_room->entities().at(id).state)) {
        return false;
      }
    }
    return true;
  }, 10.0));
  EXPECT_GT(room.counter.updates[ids[0]], 10);
}

// One receiver in ten on a 10 % loss, 30 ms link of its own (both directions), the others
// clean, the room at its defaults: every receiver converges to the relay's state once the
// publisher stops, and the lossy one was really served through its losses.
TEST(Replication, ATenthOfTheReceiversOnALossyLinkAllConverge) {
  SimWorld world({}, Room2::Config(ReplicationConfig{}));
  Client& a = world.AddClient(MintToken("rep", 1));
  NetworkConditions lossy;
  lossy.loss = 0.10;
  lossy.latency_s = 0.030;
  std::vector<Client*> receivers;
  std::vector<Counter> counts(10);
  receivers.push_back(&world.AddClientOnLink(MintToken("rep", 2), lossy, &counts[0]));
  for (uint32_t i = 1; i < 10; ++i) {
    receivers.push_back(&world.AddClient(MintToken("rep", 2 + i), &counts[i]));
  }
  std::vector<Client*> all = receivers;
  all.push_back(&a);
  ASSERT_TRUE(world.RunUntil([&] {
    for (Client* c : all) {
      if (c->state() != ClientState::kConnected) return false;
    }
    return true;
  }, 10.0));
  for (Client* c : all) ASSERT_TRUE(c->JoinRoom("rep").ok());
  ASSERT_TRUE(world.RunUntil([&] {
    for (Client* c : all) {
      if (!c->joined()) return false;
    }
    return true;
  }, 10.0));
  std::vector<uint32_t> ids;
  for (int i = 0; i < 40; ++i) ids.push_back(*a.Spawn({}));
  double next = world.Now();
  world.RunFor(4.0, [&](double now) {
    if (now < next) return;
    next += 1.0 / 30;
    for (uint32_t id : ids) {
      const float t = static_cast<float>(now) + 0.1f * static_cast<float>(id % 11);
      ASSERT_TRUE(a.PublishTransform(id, {t, std::sin(t), float(id % 7)},
                                     {0, std::sin(t / 2), 0, std::cos(t / 2)}).ok());
    }
  });
  const Room* relay_room = world.relay().FindRoom("rep");
  ASSERT_NE(relay_room, nullptr);
  auto converged = [&](const Client* c) {
    for (uint32_t id : ids) {
      const RemoteEntity* e = c->FindEntity(id);
      if (e == nullptr || !WithinPrecision(e->state, relay_room->entities().at(id).state)) {
        return false;
      }
    }
    return true;
  };
  EXPECT_TRUE(world.RunUntil([&] {
    for (const Client* c : receivers) {
      if (!converged(c)) return false;
    }
    return true;
  }, 5.0));
  for (size_t i = 0; i < receivers.size(); ++i) {
    EXPECT_TRUE(converged(receivers[i])) << "receiver " << i << (i == 0 ? " (lossy link)" : "");
    EXPECT_GT(counts[i].updates[ids[0]], 30) << "receiver " << i;
  }
  EXPECT_GT(world.link(0).down_stats().dropped, 20u);
  EXPECT_GT(world.link(0).up_stats().dropped, 5u);
}

namespace ambient {

ColliderSpec TriggerBox(Vec3f half_extents) {
  ColliderSpec c = BoxCollider(half_extents);
  c.is_trigger = true;
  return c;
}

// Two balls roll on PhyS's ground, nobody touching the first; the second rolls inside a hand's
// trigger the whole time. The untouched ball is ambient (6 Hz by default), the touched one
// normal (12 Hz); once the trigger is gone the second drops to ambient after the linger time.
TEST(Replication, UntouchedPhysSEntitiesGoAtTheAmbientRateTouchedOnesAtTheNormalRate) {
  ReplicationConfig r;  // defaults: normal 12 Hz, ambient 6 Hz, linger 2 s
  ASSERT_LT(r.ambient_hz, r.normal_hz);
  Room2 room(r);
  const uint32_t offloaded = static_cast<uint32_t>(schema::EntityFlags::Offloaded);
  const uint32_t hand_flag = static_cast<uint32_t>(schema::EntityFlags::Hand);
  SpawnDesc ground{.position = {0, -0.5f, 0}, .flags = offloaded};
  ground.colliders.push_back(BoxCollider({50, 0.5f, 50}));
  ASSERT_TRUE(room.a->Spawn(ground).ok());
  std::vector<uint32_t> balls;
  for (int i = 0; i < 2; ++i) {
    SpawnDesc ball{.position = {0, 0.1f, 3.0f * i}, .flags = offloaded};
    ball.rigid_body = RigidBodySpec{};
    ball.rigid_body->linear_velocity = {0.5f, 0, 0};  // rolls along +x for the whole test
    ball.colliders.push_back(SphereCollider(0.1f));
    balls.push_back(*room.a->Spawn(ball));
  }
  // A kinematic hand whose trigger covers the second ball's whole path (x 0..10 at z 3).
  SpawnDesc hand{.position = {5, 0.1f, 3}, .flags = offloaded | hand_flag};
  hand.rigid_body = RigidBodySpec{};
  hand.rigid_body->kinematic = true;
  hand.rigid_body->mass = 0;
  hand.colliders.push_back(TriggerBox({6, 0.5f, 0.5f}));
  auto hand_id = room.a->Spawn(hand);
  ASSERT_TRUE(hand_id.ok());
  // Past the linger time of anything the spawns stirred up.
  room.world.RunFor(r.interaction_linger_s + 0.5);
  room.counter.updates.clear();
  room.world.RunFor(3.0);
  const double untouched = room.counter.updates[balls[0]] / 3.0;
  const double touched = room.counter.updates[balls[1]] / 3.0;
  EXPECT_NEAR(untouched, r.ambient_hz, r.ambient_hz * 0.2);
  EXPECT_NEAR(touched, r.normal_hz, r.normal_hz * 0.15);

  // The hand leaves (despawned: its trigger exits); after the linger time the ball is ambient.
  ASSERT_TRUE(room.a->Despawn(*hand_id).ok());
  room.world.RunFor(r.interaction_linger_s + 0.5);
  room.counter.updates.clear();
  room.world.RunFor(3.0);
  EXPECT_NEAR(room.counter.updates[balls[1]] / 3.0, r.ambient_hz, r.ambient_hz * 0.2);
  EXPECT_NEAR(room.counter.updates[balls[0]] / 3.0, r.ambient_hz, r.ambient_hz * 0.2);
}

}  // namespace ambient

}  // namespace
}  // namespace edgephys::testing
