// A remote PhyS worker (the real edgephys-phys process) simulates a room; kill -9 of the
// worker mid-session fails the room over to embedded PhyS without losing an entity.
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <cmath>
#include <map>

#include "tests/integration/harness.h"

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
  pid_t worker = StartWorker(world.relay_endpoint());
  ASSERT_GT(worker, 0) << "cannot start " << EDGEPHYS_PHYS_BINARY;
  struct Reaper {
    pid_t pid;
    ~Reaper() {
      if (pid > 0) {
        kill(pid, SIGKILL);
        waitpid(pid, nullptr, 0);
      }
    }
  } reaper{worker};
  ASSERT_TRUE(world.RunUntil([&] { return world.counters().physics_workers.load() == 1; }, 10.0))
      << "the worker did not attach";

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

}  // namespace
}  // namespace edgephys::testing
