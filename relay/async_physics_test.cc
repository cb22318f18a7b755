// Asynchronous embedded PhyS (relay/async_physics.h) through EmbeddedPhysicsLink, with real
// Bullet worlds on real physics threads: Add is decided as the world would, commands apply in
// order, every finished step reaches the relay once, the relay side never waits for a step,
// a slow room simulates slower in single steps, and links die cleanly while their room steps.
// No assertion on speed: counts and equalities only; every loop is bounded.
#include "relay/async_physics.h"

#include <gtest/gtest.h>

#include <dirent.h>
#include <sched.h>
#include <sys/resource.h>

#include <chrono>
#include <fstream>
#include <sstream>
#include <cmath>
#include <functional>
#include <map>
#include <numeric>
#include <set>
#include <thread>

#include "loadgen/scenes/scenes.h"
#include "protocol/container_builder.h"
#include "relay/physics_link.h"

namespace edgephys {
namespace {

using Out = RoomPhysics::StepOutput;
constexpr uint32_t kInteractable = static_cast<uint32_t>(schema::EntityFlags::Interactable);

Status AddSpec(PhysicsLink& link, const EntitySpec& spec, PhysicsRole role) {
  const std::vector<uint8_t> buffer = BuildContainer(spec);
  return link.Add(AsContainer(buffer), role);
}

double Seconds() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

EntitySpec Ground(uint32_t id) { return StaticBox(id, {0, -0.5f, 0}, {20, 0.5f, 20}); }

// Everything a sequence of Advance() outputs delivered, flattened.
struct Delivered {
  int steps = 0;
  int outputs_with_steps = 0;
  std::vector<std::tuple<int, uint32_t, uint32_t>> events;
  std::vector<std::tuple<uint32_t, uint32_t, bool>> grabs;
  std::map<uint32_t, RoomPhysics::MovedBody> latest;  // by entity
  std::map<uint32_t, float> highest;                  // by entity
  bool duplicate_in_one_output = false;

  void Take(const Out& out) {
    steps += out.steps;
    outputs_with_steps += out.steps > 0;
    for (const auto& e : out.events) {
      events.emplace_back(static_cast<int>(e.type), e.entity_a, e.entity_b);
    }
    for (const auto& g : out.grabs) grabs.emplace_back(g.entity, g.hand, g.ok);
    std::set<uint32_t> seen;
    for (const auto& m : out.moved) {
      duplicate_in_one_output |= !seen.insert(m.state.entity_id).second;
      latest[m.state.entity_id] = m;
      auto [it, first] = highest.try_emplace(m.state.entity_id, m.state.position.y);
      if (!first) it->second = std::max(it->second, m.state.position.y);
    }
  }
};

// A block of nx x ny x nz boxes resting on each other on a ground: every box in contact from
// the first step, so every step solves thousands of contacts.
std::vector<EntitySpec> BoxBlock(int nx, int ny, int nz) {
  std::vector<EntitySpec> specs;
  specs.push_back(Ground(1));
  uint32_t id = physics::kSceneFirstBoxId;
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      for (int z = 0; z < nz; ++z) {
        specs.push_back(DynamicBox(id++, {0.2f * x, 0.1f + 0.2f * y, 0.2f * z},
                                   {0.1f, 0.1f, 0.1f}, 1));
      }
    }
  }
  return specs;
}

// Bodies never sleep and every step is `substeps` Bullet steps: with n = 10 and 2 substeps a
// step costs ~25 ms on a 2-core VM, with n = 12 and 4 substeps ~80 ms (the fixed step is 16.7).
physics::PhysicsConfig HeavyConfig(int substeps) {
  physics::PhysicsConfig config;
  config.sleeping = false;
  config.substeps = substeps;
  return config;
}

void AddBlock(PhysicsLink& link, int n) {
  for (const EntitySpec& s : BoxBlock(n, n, n)) {
    const PhysicsRole role = s.id == 1 ? PhysicsRole::kMirrored : PhysicsRole::kSimulated;
    ASSERT_TRUE(AddSpec(link, s, role).ok()) << s.id;
  }
}

TEST(MergeStepOutput, LatestStatePerEntityEventsAndGrabsInOrder) {
  Out a, b;
  auto moved = [](uint32_t id, float x) {
    RoomPhysics::MovedBody m;
    m.state.entity_id = id;
    m.state.position = {x, 0, 0};
    return m;
  };
  a.moved = {moved(1, 1), moved(2, 2)};
  b.moved = {moved(2, 20), moved(3, 30)};
  a.soft.push_back({.id = 7, .total = 2, .first = 0, .nodes = {{1, 1, 1}, {2, 2, 2}}});
  b.soft.push_back({.id = 7, .total = 2, .first = 0, .nodes = {{3, 3, 3}, {4, 4, 4}}});
  a.events.push_back({.entity_a = 1, .entity_b = 2});
  b.events.push_back({.entity_a = 3, .entity_b = 4});
  a.grabs.push_back({.entity = 1, .hand = 9, .ok = true});
  b.grabs.push_back({.entity = 2, .hand = 9, .ok = false, .detail = "no"});
  a.steps = 1;
  b.steps = 2;
  a.step_seconds = 0.5;
  b.step_seconds = 0.25;
  std::unordered_map<uint32_t, size_t> index;
  MergeStepOutput(&a, &b, &index);
  ASSERT_EQ(a.moved.size(), 3u);
  EXPECT_EQ(a.moved[0].state.position.x, 1);
  EXPECT_EQ(a.moved[1].state.position.x, 20);  // the later state, in the earlier place
  EXPECT_EQ(a.moved[2].state.position.x, 30);
  ASSERT_EQ(a.soft.size(), 1u);
  EXPECT_EQ(a.soft[0].nodes[0].x, 3);
  ASSERT_EQ(a.events.size(), 2u);
  EXPECT_EQ(a.events[1].entity_a, 3u);
  ASSERT_EQ(a.grabs.size(), 2u);
  EXPECT_EQ(a.grabs[0].entity, 1u);
  EXPECT_EQ(a.grabs[1].detail, "no");
  EXPECT_EQ(a.steps, 3);
  EXPECT_EQ(a.step_seconds, 0.75);
}

TEST(StepClock, PredictsWhenTheWorldSteps) {
  physics::PhysicsConfig config;
  RoomPhysics physics(config, 0.0);
  const std::vector<uint8_t> ball = BuildContainer(DynamicSphere(1, {0, 5, 0}, 0.1f, 1));
  Status added = physics.Add(AsContainer(ball), PhysicsRole::kSimulated);
  ASSERT_TRUE(added.ok()) << added.ToString();
  StepClock clock{0.0, 0.0};
  Out out;
  // Irregular calls, a backlog beyond max_substeps, a clock going back: the replay agrees.
  double now = 0;
  for (double dt : {0.004, 0.013, 0.02, 0.0167, 0.2, 0.001, 0.05, -0.01, 0.03, 0.0166, 0.0167}) {
    now += dt;
    const bool due = now >= clock.next_due(config.fixed_dt);
    physics.Advance(now, &out);
    EXPECT_EQ(due, out.steps > 0) << now;
    clock.Record(now, out.steps, config.fixed_dt);
  }
}

// Add() on an asynchronous link is decided without the world, exactly as the world decides.
TEST(AsyncPhysics, AddAcceptsAndRefusesExactlyAsTheWorld) {
  physics::PhysicsConfig config;
  AsyncPhysicsPool pool(1);
  EmbeddedPhysicsLink sync(config, 0), async(config, 0);
  async.RunOn(&pool);
  ASSERT_TRUE(async.asynchronous());
  ASSERT_FALSE(sync.asynchronous());

  struct Case {
    std::string name;
    EntitySpec spec;
    PhysicsRole role;
    bool remove_first = false;
  };
  std::vector<Case> cases;
  auto dyn = [](uint32_t id) { return DynamicBox(id, {0, 1, 0}, {0.1f, 0.1f, 0.1f}, 1); };
  cases.push_back({"ground", Ground(1), PhysicsRole::kMirrored});
  cases.push_back({"duplicate", Ground(1), PhysicsRole::kMirrored});
  cases.push_back({"zero id", dyn(0), PhysicsRole::kSimulated});
  EntitySpec orphan = dyn(2);
  orphan.parent_id = 77;
  cases.push_back({"unknown parent", orphan, PhysicsRole::kSimulated});
  EntitySpec self = dyn(2);
  self.parent_id = 2;
  cases.push_back({"own parent", self, PhysicsRole::kSimulated});
  EntitySpec node{.id = 3};  // transform-only: no rigid body
  cases.push_back({"node", node, PhysicsRole::kMirrored});
  EntitySpec child = dyn(4);
  child.parent_id = 3;
  cases.push_back({"child", child, PhysicsRole::kSimulated});
  EntitySpec nan = dyn(5);
  nan.position.x = std::nanf("");
  cases.push_back({"nan", nan, PhysicsRole::kSimulated});
  EntitySpec negative = dyn(5);
  negative.rigid_body->mass = -1;
  cases.push_back({"negative mass", negative, PhysicsRole::kSimulated});
  EntitySpec bad_child = nan;
  bad_child.parent_id = 3;  // a fault behind the parent check
  cases.push_back({"nan child", bad_child, PhysicsRole::kSimulated});
  EntitySpec jointed = dyn(6);
  jointed.joints.push_back({.connected_entity = 1});  // the static ground has a body
  cases.push_back({"joint to ground", jointed, PhysicsRole::kSimulated});
  EntitySpec dangling = dyn(7);
  dangling.joints.push_back({.connected_entity = 555});
  cases.push_back({"joint to nobody", dangling, PhysicsRole::kSimulated});
  EntitySpec to_node = dyn(7);
  to_node.joints.push_back({.connected_entity = 3});
  cases.push_back({"joint to a node", to_node, PhysicsRole::kSimulated});
  EntitySpec trigger_hand = TriggerHand(8, {}, 0.2f);
  cases.push_back({"trigger hand", trigger_hand, PhysicsRole::kMirrored});
  EntitySpec to_trigger = dyn(9);
  to_trigger.joints.push_back({.connected_entity = 8});
  cases.push_back({"joint to a trigger-only body", to_trigger, PhysicsRole::kSimulated});
  EntitySpec local = dyn(10);  // a local-physics body: mirrored as kinematic
  cases.push_back({"mirrored dynamic", local, PhysicsRole::kMirrored});
  EntitySpec to_local = dyn(11);
  to_local.joints.push_back({.connected_entity = 10});
  cases.push_back({"joint to a mirrored body", to_local, PhysicsRole::kSimulated});
  EntitySpec soft{.id = 12};
  soft.soft_body = physics::MakeLatticeCubeSoftBody(100);
  cases.push_back({"mirrored soft body", soft, PhysicsRole::kMirrored});
  cases.push_back({"simulated soft body", soft, PhysicsRole::kSimulated});
  EntitySpec crowded = dyn(13);
  crowded.colliders.assign(config.max_colliders + 1, BoxCollider({0.1f, 0.1f, 0.1f}));
  cases.push_back({"too many colliders", crowded, PhysicsRole::kSimulated});
  EntitySpec grandchild = dyn(14);
  grandchild.parent_id = 4;
  cases.push_back({"parent removed", grandchild, PhysicsRole::kSimulated, /*remove_first=*/true});
  cases.push_back({"id reused", dyn(4), PhysicsRole::kSimulated});

  for (const Case& c : cases) {
    if (c.remove_first) {
      sync.Remove(4);
      async.Remove(4);
    }
    const Status a = AddSpec(sync, c.spec, c.role), b = AddSpec(async, c.spec, c.role);
    EXPECT_EQ(a.code(), b.code()) << c.name;
    EXPECT_EQ(a.message(), b.message()) << c.name;
    EXPECT_EQ(a.reason(), b.reason()) << c.name;
  }
  // Both worlds hold the same entities, and count the same refusals.
  Out out;
  sync.Advance(0.1, &out);
  async.Advance(0.1, &out);
  pool.WaitIdle();
  async.Advance(0.1, &out);
  EXPECT_EQ(sync.counters().entities, async.counters().entities);
  EXPECT_EQ(sync.counters().bodies, async.counters().bodies);
  EXPECT_EQ(sync.counters().joints, async.counters().joints);
  EXPECT_EQ(sync.counters().rejected_containers, async.counters().rejected_containers);
}

// The same commands at the same times give the same steps, events, grab answers and states
// synchronously and asynchronously (when the relay lets each step finish): commands are
// applied in order and at the same step boundaries; outputs are neither lost nor repeated.
TEST(AsyncPhysics, SameOutputAsSynchronousForTheSameCommands) {
  physics::PhysicsConfig config;
  AsyncPhysicsPool pool(2);
  EmbeddedPhysicsLink sync(config, 0), async(config, 0);
  Delivered from_sync, from_async;
  Out out;
  auto both = [&](const std::function<void(PhysicsLink&)>& f) {
    f(sync);
    f(async);
  };
  both([](PhysicsLink& l) {
    ASSERT_TRUE(AddSpec(l, Ground(1), PhysicsRole::kMirrored).ok());
    EntitySpec ball = DynamicSphere(2, {0, 0.1f, 0}, 0.1f, 1);
    ball.flags = kInteractable;
    ASSERT_TRUE(AddSpec(l, ball, PhysicsRole::kSimulated).ok());
    EntitySpec box = DynamicBox(3, {2, 1, 0}, {0.1f, 0.1f, 0.1f}, 1);
    ASSERT_TRUE(AddSpec(l, box, PhysicsRole::kSimulated).ok());
    EntitySpec hand = TriggerHand(4, {-1, 0.1f, 0}, 0.3f);
    ASSERT_TRUE(AddSpec(l, hand, PhysicsRole::kMirrored).ok());
  });
  // Synchronous until the first step has run, as a relay's new room is.
  sync.Advance(config.fixed_dt, &out);
  from_sync.Take(out);
  async.Advance(config.fixed_dt, &out);
  from_async.Take(out);
  async.RunOn(&pool);

  for (int tick = 2; tick <= 150; ++tick) {
    const double now = tick * static_cast<double>(config.fixed_dt);
    // The hand sweeps +x through the ball, grabs it on the way (a refused early try first),
    // lifts it, lets go; the box is removed and put back higher; several drives per tick.
    const float x = -1.0f + 0.02f * static_cast<float>(tick);
    const float y = tick > 60 ? 0.1f + 0.01f * static_cast<float>(tick - 60) : 0.1f;
    both([&](PhysicsLink& l) {
      l.Drive(4, {4, {x - 0.01f, y, 0}, {}}, now - 0.004);
      if (tick == 20 || tick == 52) l.RequestGrab(2, 4, false);
      l.Drive(4, {4, {x, y, 0}, {}}, now);
      if (tick == 100) l.Release(2);
      if (tick == 70) {
        l.Remove(3);
        ASSERT_TRUE(AddSpec(l, DynamicBox(3, {2, 3, 0}, {0.1f, 0.1f, 0.1f}, 1),
                            PhysicsRole::kSimulated)
                        .ok());
        l.Restore(3, {3, {2, 3, 0}, {}}, {0, 2, 0}, {0, 0, 0});
      }
    });
    sync.Advance(now, &out);
    from_sync.Take(out);
    async.Advance(now, &out);  // picks up the previous tick's step
    from_async.Take(out);
    pool.WaitIdle();           // let this tick's step finish
  }
  async.Advance(150 * static_cast<double>(config.fixed_dt), &out);
  from_async.Take(out);

  EXPECT_EQ(from_async.steps, from_sync.steps);
  EXPECT_EQ(from_async.steps, static_cast<int>(async.counters().steps));
  EXPECT_EQ(from_async.events, from_sync.events);
  ASSERT_EQ(from_sync.grabs.size(), 2u);
  EXPECT_FALSE(std::get<2>(from_sync.grabs[0])) << "the early grab should be refused";
  EXPECT_TRUE(std::get<2>(from_sync.grabs[1])) << "the grab in the trigger should succeed";
  EXPECT_EQ(from_async.grabs, from_sync.grabs);
  EXPECT_FALSE(from_async.duplicate_in_one_output);
  ASSERT_EQ(from_async.latest.size(), from_sync.latest.size());
  for (const auto& [id, m] : from_sync.latest) {
    const auto& a = from_async.latest.at(id);
    EXPECT_EQ(a.state.position.x, m.state.position.x) << id;
    EXPECT_EQ(a.state.position.y, m.state.position.y) << id;
    EXPECT_EQ(a.state.position.z, m.state.position.z) << id;
  }
  // The ball was carried up: it really was grabbed and followed the drives.
  EXPECT_GT(from_sync.highest.at(2), 0.3f);
  EXPECT_EQ(from_async.highest, from_sync.highest);
}

// A heavy room: the relay keeps calling Advance (about every millisecond) while the physics
// thread completes one step in many of those calls; every step arrives exactly once.
TEST(AsyncPhysics, RelaySideNeverWaitsForAStepAndGetsEveryStepOnce) {
  const int n = 10;
  AsyncPhysicsPool pool(1);
  auto link = std::make_unique<EmbeddedPhysicsLink>(HeavyConfig(2), Seconds());
  AddBlock(*link, n);
  link->RunOn(&pool);
  Delivered got;
  Out out;
  int calls = 0;
  const double start = Seconds();
  while (got.outputs_with_steps < 8 && Seconds() - start < 60.0) {
    link->Advance(Seconds(), &out);
    ++calls;
    got.Take(out);
    // What the relay does between updates: a datagram or two, a tick.
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_GE(got.outputs_with_steps, 8) << "the heavy room did not step";
  const double mean_step_ms = 1000.0 * (Seconds() - start) / got.outputs_with_steps;
  // Synchronously every call would have stepped (calls == outputs); here most calls found the
  // step still running and returned at once.
  EXPECT_GT(calls, 3 * got.outputs_with_steps)
      << calls << " calls, " << got.outputs_with_steps << " outputs, ~" << mean_step_ms
      << " ms between outputs";
  EXPECT_FALSE(got.duplicate_in_one_output);

  // Nothing is lost: after the room goes idle, what arrived is what the world stepped.
  link->Advance(Seconds(), &out);
  got.Take(out);
  pool.WaitIdle();
  link->Advance(Seconds() - 1000, &out);  // a target in the past: nothing more is due
  got.Take(out);
  pool.WaitIdle();
  link->Advance(Seconds() - 1000, &out);
  got.Take(out);
  EXPECT_EQ(got.steps, static_cast<int>(link->counters().steps));
  EXPECT_EQ(got.latest.size(), static_cast<size_t>(n * n * n));  // only simulated bodies
}

// Slower than real time: one step per output (no catch-up bursts), a real-time factor below 1.
TEST(AsyncPhysics, ASlowRoomSimulatesSlowerInSingleSteps) {
  const physics::PhysicsConfig config = HeavyConfig(4);
  AsyncPhysicsPool pool(1);
  EmbeddedPhysicsLink link(config, Seconds());
  AddBlock(link, 12);
  link.RunOn(&pool);
  Out out;
  std::vector<int> steps_per_output;
  double cost = 0;
  const double start = Seconds();
  while (Seconds() - start < 30.0 &&
         (steps_per_output.size() < 6 || std::isnan(link.realtime_factor()))) {
    link.Advance(Seconds(), &out);
    if (out.steps > 0) {
      steps_per_output.push_back(out.steps);
      cost += out.step_seconds;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
  ASSERT_GE(steps_per_output.size(), 6u);
  const double per_step = cost / std::accumulate(steps_per_output.begin(), steps_per_output.end(), 0);
  if (per_step <= 2 * config.fixed_dt) {
    GTEST_SKIP() << "this machine steps the scene too fast (" << per_step << " s per step)";
  }
  ASSERT_FALSE(std::isnan(link.realtime_factor()));
  EXPECT_LT(link.realtime_factor(), 1.0);
  // Once the room is known to be slow (after its first output), each output is one step.
  for (size_t i = 1; i < steps_per_output.size(); ++i) EXPECT_EQ(steps_per_output[i], 1) << i;
}

// Links destroyed while their room steps, the pool destroyed while others step: no wait on
// the relay's side for the first, a clean stop for the second.
TEST(AsyncPhysics, DestructionWhileSteppingIsClean) {
  Out out;
  for (int round = 0; round < 3; ++round) {
    AsyncPhysicsPool pool(2);
    std::vector<std::unique_ptr<EmbeddedPhysicsLink>> links;
    for (int i = 0; i < 3; ++i) {
      links.push_back(std::make_unique<EmbeddedPhysicsLink>(HeavyConfig(2), Seconds()));
      AddBlock(*links.back(), 8);
      links.back()->RunOn(&pool);
    }
    // Start steps (targets a step ahead), queue commands, then drop links mid-step.
    const double now = Seconds() + 0.05;
    for (auto& l : links) {
      l->Advance(now, &out);
      l->Drive(1, {1, {0, -0.4f, 0}, {}}, now);
      l->RequestGrab(physics::kSceneFirstBoxId, 1, true);
      l->Remove(physics::kSceneFirstBoxId + 1);
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(2 + 5 * round));
    links[0].reset();
    links[1]->Advance(now + 0.05, &out);
    links[1].reset();
    if (round == 2) {
      pool.WaitIdle();  // the survivor finishes; the closed ones are freed
      links[2]->Advance(now + 0.1, &out);
    }
    links[2].reset();
    // The pool (destroyed here) stops its threads after their current step and joins them.
  }
}



// Field `index` (1-based, as in proc(5)) of /proc/self/task/*/stat for every thread of this
// process named `name`: 19 is the niceness, 41 the scheduling policy.
std::vector<int> StatFieldOfThreadsNamed(const std::string& name, int index) {
  std::vector<int> out;
  DIR* dir = opendir("/proc/self/task");
  if (dir == nullptr) return out;
  while (dirent* d = readdir(dir)) {
    if (d->d_name[0] == '.') continue;
    const std::string task = std::string("/proc/self/task/") + d->d_name;
    std::string comm;
    std::getline(std::ifstream(task + "/comm"), comm);
    if (comm != name) continue;
    std::string stat;
    std::getline(std::ifstream(task + "/stat"), stat);
    std::istringstream rest(stat.substr(stat.rfind(')') + 2));  // after "pid (comm) "
    std::string field;
    for (int i = 3; i <= index && rest >> field; ++i) {
      if (i == index) out.push_back(std::stoi(field));
    }
  }
  closedir(dir);
  return out;
}

std::vector<int> NicenessOfThreadsNamed(const std::string& name) {
  return StatFieldOfThreadsNamed(name, 19);
}

TEST(AsyncPhysics, PhysicsThreadsLowerTheirOwnPriorityByTheNicenessAsked) {
  const int base = getpriority(PRIO_PROCESS, 0);
  ASSERT_LE(base, 14) << "the test process already runs at a niceness above 14";
  {
    AsyncPhysicsPool pool(2, 5);
    for (int i = 0; i < 200 && pool.threads_reniced() < 2; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    EXPECT_EQ(pool.threads_reniced(), 2u);
    EXPECT_EQ(pool.nice(), 5);
    const std::vector<int> nice = NicenessOfThreadsNamed("edgephys-physs");
    ASSERT_EQ(nice.size(), 2u);
    for (int n : nice) EXPECT_EQ(n, base + 5);
  }
  EXPECT_EQ(getpriority(PRIO_PROCESS, 0), base);  // the calling thread keeps its priority
  AsyncPhysicsPool same(1);                        // 0: unchanged
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(same.threads_reniced(), 0u);
  const std::vector<int> nice = NicenessOfThreadsNamed("edgephys-physs");
  ASSERT_EQ(nice.size(), 1u);
  EXPECT_EQ(nice[0], base);
}

TEST(AsyncPhysics, IdlePhysicsThreadsRunUnderSchedIdleAndTheCallerKeepsItsPolicy) {
  const int caller_policy = sched_getscheduler(0);
  ASSERT_NE(caller_policy, SCHED_IDLE) << "the test process already runs under SCHED_IDLE";
  {
    AsyncPhysicsPool pool(2, 5, /*idle=*/true);
    for (int i = 0; i < 200 && pool.threads_reniced() < 2; ++i) {
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    EXPECT_EQ(pool.threads_reniced(), 2u);
    EXPECT_TRUE(pool.idle());
    const std::vector<int> policy = StatFieldOfThreadsNamed("edgephys-physs", 41);
    ASSERT_EQ(policy.size(), 2u);
    for (int p : policy) EXPECT_EQ(p, SCHED_IDLE);
  }
  EXPECT_EQ(sched_getscheduler(0), caller_policy);
  // Without `idle` the threads keep the normal policy (niceness is the only change).
  AsyncPhysicsPool normal(1, 5);
  for (int i = 0; i < 200 && normal.threads_reniced() < 1; ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  const std::vector<int> policy = StatFieldOfThreadsNamed("edgephys-physs", 41);
  ASSERT_EQ(policy.size(), 1u);
  EXPECT_EQ(policy[0], SCHED_OTHER);
}

}  // namespace

}  // namespace edgephys
