// A remote PhyS worker (the real edgephys-phys process) simulates a room; kill -9 of the
// worker mid-session fails the room over to embedded PhyS without losing an entity, and a
// soft body keeps the deformation it had.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <algorithm>
#include <cmath>
#include <map>

#include "loadgen/scenes/scenes.h"
#include "tests/integration/harness.h"
#include "tests/integration/plated_bunny.h"

extern char** environ;

namespace edgephys::testing {
namespace {

using schema::EntityFlags;

pid_t StartWorker(const Endpoint& relay) {
  std::string address = "127.0.0.1:" + std::to_string(relay.port());
  std::vector<std::string> args = {EDGEPHYS_PHYS_BINARY, "--relay", address, "--worker-key",
                                   kSecret, "--log-level", "warn", "--run-for", "60"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  return pid;
}

// A worker process attached to a LoopbackWorld's relay; SIGKILLed and reaped on destruction
// unless the test did that itself (and set pid to 0).
struct WorkerProcess {
  pid_t pid = 0;
  void StartAttached(LoopbackWorld& world) {
    pid = StartWorker(world.relay_endpoint());
    ASSERT_GT(pid, 0) << "cannot start " << EDGEPHYS_PHYS_BINARY;
    ASSERT_TRUE(world.RunUntil([&] { return world.counters().physics_workers.load() == 1; }, 10.0))
        << "the worker did not attach";
  }
  ~WorkerProcess() {
    if (pid > 0) {
      kill(pid, SIGKILL);
      waitpid(pid, nullptr, 0);
    }
  }
};

struct Trace : ClientListener {
  // entity -> (time, position) of every update received
  std::map<uint32_t, std::vector<std::pair<double, Vec3f>>> samples;
  const LoopbackWorld* world = nullptr;
  void OnEntityUpdated(const RemoteEntity& e) override {
    samples[e.id].emplace_back(world->Now(), e.state.position);
  }
};

TEST(PhysicsWorker, KillMinusNineFailsOverWithinASecondKeepingEveryEntityContinuous) {
  LoopbackWorld world;
  WorkerProcess reaper;
  ASSERT_NO_FATAL_FAILURE(reaper.StartAttached(world));
  const pid_t worker = reaper.pid;

  Trace trace;
  trace.world = &world;
  Client& a = world.AddClient(MintToken("w", 1));
  Client& b = world.AddClient(MintToken("w", 2), &trace);
  for (Client* c : {&a, &b}) {
    ASSERT_TRUE(world.RunUntil([&] { return c->state() == ClientState::kConnected; }, 3.0));
    ASSERT_TRUE(c->JoinRoom("w").ok());
  }
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 3.0));
  const uint32_t offloaded = static_cast<uint32_t>(EntityFlags::Offloaded);
  SpawnDesc ground{.position = {0, -0.5f, 0}, .flags = offloaded};
  ground.colliders.push_back(BoxCollider({50, 0.5f, 50}));
  ASSERT_TRUE(a.Spawn(ground).ok());
  std::vector<uint32_t> balls;
  for (int i = 0; i < 6; ++i) {
    SpawnDesc ball{.position = {0, 0.1f, static_cast<float>(i)}, .flags = offloaded};
    ball.rigid_body = RigidBodySpec{};
    ball.rigid_body->linear_velocity = {0.6f + 0.1f * i, 0, 0};  // rolling along +x
    ball.colliders.push_back(SphereCollider(0.1f));
    balls.push_back(*a.Spawn(ball));
  }
  ASSERT_TRUE(world.RunUntil([&] { return world.relay().PhysicsWorkerOf("w") != 0; }, 3.0));
  world.RunFor(1.5);
  for (uint32_t id : balls) {
    // Nobody touches the balls: the ambient class, 6 Hz by default, for 1.5 s (about 9).
    ASSERT_GT(trace.samples[id].size(), 6u) << "the worker did not simulate ball " << id;
    EXPECT_GT(trace.samples[id].back().second.x, 0.3f);
  }

  const double killed_at = world.Now();
  ASSERT_EQ(kill(worker, SIGKILL), 0);
  waitpid(worker, nullptr, 0);
  reaper.pid = 0;
  world.RunFor(2.5);

  EXPECT_EQ(world.counters().physics_failovers.load(), 1u);
  EXPECT_EQ(world.relay().PhysicsWorkerOf("w"), 0u);  // now embedded
  EXPECT_EQ(world.relay().FindRoom("w")->entities().size(), balls.size() + 1);
  for (uint32_t id : balls) {
    ASSERT_NE(b.FindEntity(id), nullptr);
    const auto& s = trace.samples[id];
    // The room continues within 1 s: updates resume, and the ball keeps rolling.
    double resumed = -1;
    for (size_t k = 1; k < s.size(); ++k) {
      if (s[k].first > killed_at + 0.05 && s[k].second.x != s[k - 1].second.x) {
        resumed = s[k].first;
        break;
      }
    }
    ASSERT_GT(resumed, 0) << "ball " << id << " never moved again";
    EXPECT_LT(resumed - killed_at, 1.0) << "ball " << id;
    EXPECT_GT(s.back().second.x, s.front().second.x + 1.0f);
    // Continuous: between consecutive updates a ball moves no more than its rolling speed
    // (< 1.2 m/s) allows, plus 5 cm: no jump back to an old state, none ahead.
    double max_jump = 0;
    for (size_t k = 1; k < s.size(); ++k) {
      float dx = s[k].second.x - s[k - 1].second.x, dy = s[k].second.y - s[k - 1].second.y,
            dz = s[k].second.z - s[k - 1].second.z;
      double moved = std::sqrt(dx * dx + dy * dy + dz * dz);
      double allowed = 1.2 * (s[k].first - s[k - 1].first);
      max_jump = std::max(max_jump, moved - allowed);
      EXPECT_GE(dx, -0.05f) << "ball " << id << " jumped back";
    }
    EXPECT_LT(max_jump, 0.05) << "ball " << id;
  }
}

float MaxDistance(const std::vector<Vec3f>& a, const std::vector<Vec3f>& b);

struct SoftTrace : ClientListener {
  uint32_t id = 0;
  std::vector<Vec3f> nodes;  // the latest particles received
  double updated_at = -1;
  const LoopbackWorld* world = nullptr;
  // While set: the largest particle move between two consecutive updates (the body's own
  // motion as this receiver sees it in normal running).
  bool track_jumps = false;
  float largest_jump = 0;
  void OnSoftBodyUpdated(const RemoteEntity& e) override {
    if (e.id != id) return;
    if (track_jumps && nodes.size() == e.nodes.size()) {
      largest_jump = std::max(largest_jump, MaxDistance(nodes, e.nodes));
    }
    nodes = e.nodes;
    updated_at = world->Now();
  }
};

// The q-quantile (0..1) of the particles' distances between two versions of a body.
float DistanceQuantile(const std::vector<Vec3f>& a, const std::vector<Vec3f>& b, double q) {
  if (a.size() != b.size() || a.empty()) return 1e9f;
  std::vector<float> d(a.size());
  for (size_t i = 0; i < a.size(); ++i) {
    const float dx = a[i].x - b[i].x, dy = a[i].y - b[i].y, dz = a[i].z - b[i].z;
    d[i] = std::sqrt(dx * dx + dy * dy + dz * dz);
  }
  std::sort(d.begin(), d.end());
  return d[std::min(d.size() - 1, static_cast<size_t>(q * static_cast<double>(d.size())))];
}

float MaxDistance(const std::vector<Vec3f>& a, const std::vector<Vec3f>& b) {
  float worst = a.size() == b.size() ? 0.0f : 1e9f;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
    const float dx = a[i].x - b[i].x, dy = a[i].y - b[i].y, dz = a[i].z - b[i].z;
    worst = std::max(worst, std::sqrt(dx * dx + dy * dy + dz * dz));
  }
  return worst;
}

// A plate squashes a bunny simulated on the worker; kill -9 of the worker while the plate holds
// it: after the failover the receiver's particles are where they were before, not back at the
// spawn shape (issue 15). "Before" is the last version the receiver got from the dead worker;
// "after" is the first version from the new world, which the relay sends at once. The squashed
// body jitters under the plate on its own (its contact particles move 5-9 mm per 1/60 s step,
// and 4-13 mm between two 12 Hz updates in normal running), so the bound for every particle is
// that of the body's own motion over one or two steps.
// Soft bodies go as format 11 (residuals against acknowledged versions).
TEST(SoftFailover, KillMinusNineDuringASoftBodyDeformationKeepsTheDeformedParticles) {
  LoopbackWorld world(LoopbackWorld::DefaultConfig());
  WorkerProcess reaper;
  ASSERT_NO_FATAL_FAILURE(reaper.StartAttached(world));
  const pid_t worker = reaper.pid;
  SoftTrace trace;
  trace.world = &world;
  PlatedBunny stage;
  ASSERT_NO_FATAL_FAILURE(StagePlatedBunny(world, "s", &trace, &stage));
  Client& a = *stage.host;
  trace.id = stage.bunny;
  const size_t particles = stage.particles;
  // The plate: A's own kinematic body, mirrored into PhyS, moved by A's pose updates.
  float plate_y = stage.plate_y;
  ASSERT_TRUE(world.RunUntil([&] { return world.relay().PhysicsWorkerOf("s") != 0; }, 3.0));
  ASSERT_TRUE(world.RunUntil([&] { return trace.nodes.size() == particles; }, 5.0))
      << "the worker did not simulate the bunny";
  world.RunFor(1.5);  // landed
  float top = -1e9f;
  for (const Vec3f& q : trace.nodes) top = std::max(top, q.y);
  const float target = 0.8f * top + 0.05f;  // the plate's face at 80 % of the bunny's height
  const double lower_from = world.Now();
  world.RunFor(5.0, [&](double now) {  // down at 0.3 m/s (about 2 s), then held
    plate_y = std::max(target, 1.5f - 0.3f * static_cast<float>(now - lower_from));
    (void)a.PublishTransform(stage.plate, {0, plate_y, 0}, {});
  });
  ASSERT_EQ(plate_y, target);
  float squashed_top = -1e9f;
  for (const Vec3f& q : trace.nodes) squashed_top = std::max(squashed_top, q.y);
  ASSERT_LT(squashed_top, 0.9f * top) << "the plate did not squash the bunny";

  const std::vector<Vec3f> half_second_before = trace.nodes;  // how much it moves by itself
  trace.track_jumps = true;
  world.RunFor(0.5, [&](double) { (void)a.PublishTransform(stage.plate, {0, plate_y, 0}, {}); });
  trace.track_jumps = false;
  const std::vector<Vec3f> at_kill = trace.nodes;  // what B showed when the worker died
  const double killed_at = world.Now();
  ASSERT_EQ(kill(worker, SIGKILL), 0);
  waitpid(worker, nullptr, 0);
  reaper.pid = 0;
  double failed_over_at = -1;
  std::vector<Vec3f> before = at_kill;  // B's last particles from the dead worker
  std::vector<Vec3f> first_after;  // B's particles once a full version came from the new world
  double since = -1;
  world.RunFor(3.0, [&](double now) {
    (void)a.PublishTransform(stage.plate, {0, plate_y, 0}, {});  // the plate keeps holding
    if (failed_over_at < 0 && world.counters().physics_failovers.load() == 1) failed_over_at = now;
    // A version goes out as a few chunks in one tick: 20 ms after the first update from the
    // new world, every particle B holds comes from it (the next is due 83 ms later).
    if (failed_over_at >= 0 && since < 0 && trace.updated_at > failed_over_at) since = now;
    if (since < 0) before = trace.nodes;
    if (since >= 0 && first_after.empty() && now > since + 0.02) first_after = trace.nodes;
  });
  ASSERT_EQ(world.counters().physics_failovers.load(), 1u);
  EXPECT_EQ(world.relay().PhysicsWorkerOf("s"), 0u);  // now embedded
  ASSERT_FALSE(first_after.empty()) << "no particles after the failover";
  const float jump = MaxDistance(before, first_after);
  const float p95 = DistanceQuantile(before, first_after, 0.95);
  const float creep = MaxDistance(half_second_before, at_kill);
  std::printf("[soft failover] detected %.3f s after the kill, first new version %.3f s after "
              "that; particles after vs before: p95 %.4f m, max %.4f m (against B's particles "
              "at the kill: p95 %.4f m, max %.4f m). The body's own motion before the kill: "
              "largest move between two updates %.4f m, over 0.5 s %.4f m\n",
              failed_over_at - killed_at, since - failed_over_at, p95, jump,
              DistanceQuantile(at_kill, first_after, 0.95), MaxDistance(at_kill, first_after),
              trace.largest_jump, creep);
  // Every particle within 1 cm of the last version from the dead worker (from the spawn shape,
  // as before issue 15, they were about 1 m off); 95 % within 5 mm. Against what B showed at
  // the kill (printed, not asserted), B's lag of up to one 12 Hz update adds the body's own
  // motion over it, which reached 17 mm in one run.
  EXPECT_LT(p95, 0.005f) << "the soft body did not resume from its deformed state";
  EXPECT_LT(jump, 0.01f) << "the soft body did not resume from its deformed state";
  // At once: the first version from the new world within a room tick or two (30 Hz), not a
  // send interval (83 ms) later.
  EXPECT_LT(since - failed_over_at, 0.075);
  float top_after = -1e9f;
  for (const Vec3f& q : trace.nodes) top_after = std::max(top_after, q.y);
  EXPECT_LT(top_after, 0.9f * top) << "the bunny sprang back to its spawn shape";
}

}  // namespace
}  // namespace edgephys::testing
