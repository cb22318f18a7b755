#include "loadgen/softbody.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <thread>
#include <unordered_map>

#include "loadgen/loopback_room.h"
#include "loadgen/paper_figures.h"
#include "loadgen/relay_window_result.h"
#include "loadgen/softbody_scene.h"
#include "loadgen/stats.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::loadgen {
namespace {

constexpr size_t kRing = 16;  // recent relay particle versions kept per bunny

void Bench(const SoftBodyOptions& o, uint32_t n, SoftBodyResult* r) {
  SoftBodyScene scene = MakeSoftBodyScene(o, n);
  physics::PhysicsConfig config;
  physics::PhysicsWorld world(config);
  for (const EntitySpec& s : scene.specs) {
    const std::vector<uint8_t> buf = BuildContainer(s);
    if (!world.AddEntity(AsContainer(buf)).ok()) {
      std::fprintf(stderr, "softbody: the standalone world refused entity %u\n", s.id);
      return;
    }
  }
  std::vector<EntityState> moved;
  std::vector<physics::PhysicsEvent> events;
  std::vector<Vec3f> nodes;
  int64_t poke_steps = -1000000;  // steps since the hands were aimed (negative: waiting)
  auto step = [&] {
    ++poke_steps;
    const auto a = std::chrono::steady_clock::now();
    for (uint32_t i = 0; i < n; ++i) {
      Vec3f pos;
      scene.HandPose(i, static_cast<double>(poke_steps) * config.fixed_dt, &pos);
      (void)world.MoveToTransform(kFirstHandId + i, pos, Quatf{});
    }
    world.Step();
    world.CollectStates(&moved);
    events.clear();
    world.DrainEvents(&events);
    for (const EntityState& st : moved) {
      if (st.entity_id >= kFirstBunnyId && st.entity_id < kFirstBunnyId + n) {
        (void)world.GetSoftBodyNodes(st.entity_id, &nodes);
      }
    }
    return Seconds(std::chrono::steady_clock::now() - a) * 1000.0;
  };
  for (int i = 0; i < o.bench_warmup_steps; ++i) (void)step();
  for (uint32_t i = 0; i < n; ++i) {
    if (world.GetSoftBodyNodes(kFirstBunnyId + i, &nodes).ok()) scene.Calibrate(i, nodes);
  }
  poke_steps = 0;
  std::vector<double> ms;
  const auto m0 = std::chrono::steady_clock::now();
  for (int i = 0; i < o.bench_steps; ++i) {
    if (i >= 30 && Seconds(std::chrono::steady_clock::now() - m0) > o.bench_max_s) break;
    ms.push_back(step());
  }
  r->bench_steps = static_cast<int>(ms.size());
  r->step_ms_median = Median(ms);
  r->step_ms_p99 = Percentile(ms, 99);
}

struct BunnyTable {
  std::unordered_map<uint32_t, size_t> index;             // entity id -> bunny index
  std::vector<std::vector<std::vector<Vec3f>>> ring;      // per bunny: recent relay versions
  std::vector<uint32_t> count;
};

class SoftReceiver : public ClientListener {
 public:
  explicit SoftReceiver(const BunnyTable* bunnies) : bunnies_(bunnies) {}
  void OnSoftBodyUpdated(const RemoteEntity& e) override {
    if (!measuring) return;
    auto it = bunnies_->index.find(e.id);
    if (it == bunnies_->index.end()) return;
    ++updates;
    const size_t k = it->second;
    // Compare only once the ring holds kRing versions: at the start of the window the
    // receiver's particles may come from versions sent before the ring began recording.
    if (bunnies_->count[k] < kRing) return;
    const size_t versions = kRing;
    double worst = 0;
    for (size_t p = 0; p < e.nodes.size(); ++p) {
      double best = 1e9;
      for (size_t v = 0; v < versions; ++v) {
        const auto& relay_nodes = bunnies_->ring[k][v];
        if (p < relay_nodes.size()) best = std::min(best, Dist(e.nodes[p], relay_nodes[p]));
      }
      worst = std::max(worst, best);
    }
    sent_errors.push_back(worst);
  }
  bool measuring = false;
  uint64_t updates = 0;
  std::vector<double> sent_errors;

 private:
  const BunnyTable* bunnies_;
};

void RelayRun(const SoftBodyOptions& o, uint32_t n, SoftBodyResult* r) {
  SoftBodyScene scene = MakeSoftBodyScene(o, n);
  RelayConfig config =
      BenchmarkRelayConfig(o.receivers, 2 * n + 16, o.position_step_m, o.rotation_bound_deg);
  if (o.soft_touched_hz > 0) config.room_defaults.replication.soft_touched_hz = o.soft_touched_hz;
  const double dt = config.physics.fixed_dt;

  BunnyTable bunnies;
  auto [receivers, listeners] = MakeReceiverSet<SoftReceiver>(o.receivers, nullptr, &bunnies);
  ClientConfig host_config;
  host_config.publish_rate_hz = 120;
  LoopbackRoom world(config, "softbody", o.receivers + 1, host_config, listeners);
  if (!world.ConnectAndJoin(5.0)) {
    std::fprintf(stderr, "softbody: clients failed to connect/join\n");
    return;
  }
  Client& host = world.client(0);
  RelayCounters& counters = world.counters();

  std::vector<uint32_t> bunny_ids, hand_ids;
  for (const EntitySpec& s : scene.specs) {
    auto id = host.Spawn(OffloadedSpawn(s));
    if (!id.ok()) {
      std::fprintf(stderr, "softbody: spawn failed: %s\n", std::string(id.status().message()).c_str());
      return;
    }
    if (s.soft_body) {
      bunnies.index[*id] = bunny_ids.size();
      bunny_ids.push_back(*id);
    }
    if (s.id >= kFirstHandId) hand_ids.push_back(*id);
  }
  bunnies.ring.assign(n, std::vector<std::vector<Vec3f>>(kRing));
  bunnies.count.assign(n, 0);

  uint64_t poke_start = ~uint64_t{0};  // PhyS step the pokes start at (after settling)
  auto drive_hands = [&] {
    const uint64_t steps = RelayCounters::Get(counters.physics_steps);
    const double sim_t = steps >= poke_start ? static_cast<double>(steps - poke_start) * dt : -1.0;
    scene.PublishHands(host, hand_ids, sim_t);
  };
  auto round = [&] {
    drive_hands();
    world.Step();
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  };

  // Everyone has the scene, bunnies with their particles.
  const double spawn_start = world.Now();
  bool ready = false;
  while (!ready && world.Now() - spawn_start < 30.0) {
    round();
    const Room* room = world.room();
    if (room == nullptr || room->entities().size() < scene.specs.size()) continue;
    ready = true;
    for (size_t c = 1; c < world.client_count() && ready; ++c) {
      for (size_t k = 0; k < bunny_ids.size() && ready; ++k) {
        const RemoteEntity* e = world.client(c).FindEntity(bunny_ids[k]);
        ready = e != nullptr && e->spawned && !e->nodes.empty();
      }
    }
  }
  if (!ready) {
    std::fprintf(stderr, "softbody: the scene did not reach every client within 30 s\n");
    return;
  }
  const Room* room = world.room();
  std::vector<const Entity*> relay_bunnies;
  for (uint32_t id : bunny_ids) relay_bunnies.push_back(&room->entities().at(id));
  std::vector<uint32_t> seen_version(n, 0);

  const double settle_start = world.Now();
  RunPhysicsSteps(world, static_cast<uint64_t>(o.relay_settle_steps), o.relay_settle_max_s, round);
  // Aim the hands at the bunnies as the host sees them, let them start poking.
  for (size_t k = 0; k < bunny_ids.size(); ++k) {
    const RemoteEntity* e = host.FindEntity(bunny_ids[k]);
    scene.Calibrate(k, e != nullptr && !e->nodes.empty() ? e->nodes : relay_bunnies[k]->nodes);
  }
  poke_start = RelayCounters::Get(counters.physics_steps);
  const uint64_t poke_warm = poke_start + static_cast<uint64_t>(0.25 / dt);
  while (RelayCounters::Get(counters.physics_steps) < poke_warm && world.Now() - settle_start < 2 * o.relay_settle_max_s) {
    round();
  }

  const size_t R = o.receivers;
  for (size_t k = 0; k < R; ++k) receivers[k]->measuring = true;
  WindowMeter meter;
  meter.Start(world, R);
  const double t0 = world.Now();
  double next_sample = t0, last_progress = 0;
  std::vector<double> same_errors, deformation;
  while (world.Now() < t0 + o.duration_s) {
    drive_hands();
    world.UpdateRelay();
    for (size_t k = 0; k < relay_bunnies.size(); ++k) {
      if (relay_bunnies[k]->nodes_version == seen_version[k]) continue;
      seen_version[k] = relay_bunnies[k]->nodes_version;
      bunnies.ring[k][bunnies.count[k]++ % kRing] = relay_bunnies[k]->nodes;
    }
    world.UpdateClients();
    const double now = world.Now();
    if (now >= next_sample) {
      next_sample += 0.1;
      for (size_t c = 1; c < world.client_count(); ++c) {
        for (size_t k = 0; k < bunny_ids.size(); ++k) {
          const RemoteEntity* e = world.client(c).FindEntity(bunny_ids[k]);
          const auto& truth = relay_bunnies[k]->nodes;
          if (e == nullptr || e->nodes.size() != truth.size()) continue;
          double worst = 0;
          for (size_t p = 0; p < truth.size(); ++p) worst = std::max(worst, Dist(e->nodes[p], truth[p]));
          same_errors.push_back(worst);
        }
      }
      const double d = scene.Deformation(0, relay_bunnies[0]->nodes);
      deformation.push_back(d);
    }
    if (o.progress && now - last_progress >= 0.5) {
      last_progress = now;
      std::fprintf(stderr, "\r  %u bunnies  relay: measuring %4.1f / %.1f s   ", n, now - t0, o.duration_s);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  const WindowMeter::Totals window = meter.Finish(world);
  const double elapsed = window.elapsed_s;
  double updates = 0;
  std::vector<double> sent;
  for (size_t k = 0; k < R; ++k) {
    updates += static_cast<double>(receivers[k]->updates);
    sent.insert(sent.end(), receivers[k]->sent_errors.begin(), receivers[k]->sent_errors.end());
  }
  const double per = static_cast<double>(R) * elapsed;
  SetRelayWindowRates(r, window, R, dt);
  r->soft_updates_per_s_per_client = updates / per;
  r->deformation_min_m = deformation.empty() ? 0 : *std::min_element(deformation.begin(), deformation.end());
  r->deformation_max_m = Max(deformation);
  r->node_err_max_m = Max(same_errors);
  r->node_err_p99_m = Percentile(same_errors, 99);
  r->node_err_sent_max_m = Max(sent);
  r->node_err_sent_p99_m = Percentile(sent, 99);
  r->error_samples = same_errors.size();
}

}  // namespace

std::vector<SoftBodyResult> RunSoftBody(const SoftBodyOptions& o) {
  std::vector<SoftBodyResult> results;
  for (uint32_t n : o.bunnies) {
    SoftBodyResult r;
    r.bunnies = n;
    r.paper_mbit_per_s = PaperBunnyMbitPerS(n);
    r.particles = MakeSoftBodyScene(o, n).particles;
    if (o.progress) std::fprintf(stderr, "\r  %u bunnies  standalone step time ...   ", n);
    Bench(o, n, &r);
    if (o.external.enabled()) {
      ExternalSoftBodyRun(o, n, &r);
    } else {
      RelayRun(o, n, &r);
    }
    if (o.progress) std::fprintf(stderr, "\r%70s\r", "");
    results.push_back(r);
  }
  return results;
}

}  // namespace edgephys::loadgen
