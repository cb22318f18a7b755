// multiobject against an EXTERNAL edgephys-relay (--relay HOST:PORT --secret S): the same scene
// and clients as the in-process run, over real sockets, with the server-side figures read
// from the relay's /metrics (loadgen/relay_target.h). What needs the relay's own entity table
// (errors against its truth, the display probe) is unknown here and reported as null.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <thread>
#include <unordered_map>

#include "loadgen/external_room.h"
#include "loadgen/loopback_room.h"
#include "loadgen/multiobject.h"
#include "loadgen/relay_target.h"
#include "loadgen/relay_window_result.h"
#include "loadgen/stats.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::loadgen {
namespace {

// A receiver: counts the boxes it holds and the updates it receives while measuring.
struct ExternalReceiver : ClientListener {
  explicit ExternalReceiver(const std::unordered_map<uint32_t, size_t>* box_index) : boxes(box_index) {}
  void OnEntitySpawned(const RemoteEntity& e) override {
    if (boxes->count(e.id) != 0) ++spawned;
  }
  void OnEntityUpdated(const RemoteEntity& e) override {
    if (measuring && boxes->count(e.id) != 0) ++updates;
  }
  void OnPhysicsEvent(uint8_t, uint32_t, uint32_t) override {
    if (measuring) ++events;
  }
  const std::unordered_map<uint32_t, size_t>* boxes;
  size_t spawned = 0;
  bool measuring = false;
  uint64_t updates = 0, events = 0;
};

void Unknown(MultiObjectResult* r) {
  r->pos_err_max_m = r->pos_err_p99_m = r->pos_err_sent_max_m = r->pos_err_sent_p99_m = kUnknown;
  r->display_err_p50_m = r->display_err_p99_m = kUnknown;
  r->display_err_hermite_p50_m = r->display_err_hermite_p99_m = kUnknown;
  r->display_err_adaptive_p50_m = r->display_err_adaptive_p99_m = r->display_adaptive_playout_ms_median = kUnknown;
  r->display_rot_err_p50_deg = r->display_rot_err_p99_deg = kUnknown;
  r->display_delay_ms_median = r->display_playout_ms_median = kUnknown;
}

}  // namespace

void ExternalMultiObjectRun(const MultiObjectOptions& o, uint32_t n, MultiObjectResult* r) {
  Unknown(r);
  const physics::MultiObjectParams p = MultiObjectSceneParams(o, n);
  const double dt = p.config.fixed_dt;
  std::unordered_map<uint32_t, size_t> box_index;
  ExternalSceneRoom<ExternalReceiver> world(o.external, "multiobject-" + std::to_string(n),
                                            o.receivers, &box_index);
  if (!world.JoinAll(15)) return;
  const auto& receivers = world.receivers;
  auto now = [&] { return world.Now(); };

  // The host dissects the scene as in the in-process run.
  Client& host = world.client(0);
  const double spawn_start = now();
  uint32_t stirrer = 0;
  for (const EntitySpec& s : physics::MultiObjectSpecs(p)) {
    auto id = host.Spawn(OffloadedSpawn(s));
    if (!id.ok()) {
      std::fprintf(stderr, "multiobject: spawn %zu refused by the relay: %s (raise its budgets: "
                   "see docs/operations.md)\n", box_index.size(),
                   std::string(id.status().message()).c_str());
      return;
    }
    if (s.id == physics::kSceneStirrerId) stirrer = *id;
    if (s.id >= physics::kSceneFirstBoxId) box_index.emplace(*id, box_index.size());
  }

  // The stirrer runs on the relay's PhyS clock (ExternalRoom::PhysicsSteps).
  double sim_t0 = -1;
  auto sim_steps = [&] { return world.PhysicsSteps(); };
  auto round = [&] {
    if (sim_t0 < 0) sim_t0 = sim_steps();
    Vec3f pos;
    Quatf rot;
    physics::StirrerPose(p, (sim_steps() - sim_t0) * dt, &pos, &rot);
    (void)host.PublishTransform(stirrer, pos, rot);
    world.Update();
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  };

  // Everyone has the whole scene.
  bool spawned = false;
  while (now() - spawn_start < 120.0) {
    round();
    spawned = std::all_of(receivers.begin(), receivers.end(),
                          [&](const auto& l) { return l->spawned >= box_index.size(); });
    if (spawned) break;
    if (world.host_watch.refused()) {
      std::fprintf(stderr, "\nmultiobject: the relay refused the scene: %s (raise its budgets: "
                   "docs/operations.md, \"Room budgets\")\n", world.host_watch.what().c_str());
      return;
    }
    if (o.progress) {
      std::fprintf(stderr, "\r  %6u objects  external relay: spawning (%zu / %zu at receiver 1)  ",
                   n, receivers[0]->spawned, box_index.size());
    }
  }
  if (!spawned) {
    std::fprintf(stderr, "\nmultiobject: the scene did not reach every client within 120 s\n");
    return;
  }
  r->spawn_s = now() - spawn_start;

  // Settle: relay_settle_steps PhyS steps (by the relay's counter), at most relay_settle_max_s.
  if (o.progress) std::fprintf(stderr, "\r  %6u objects  external relay: settling             ", n);
  const double settle_from = sim_steps(), settle_start = now();
  while (sim_steps() - settle_from < o.relay_settle_steps && now() - settle_start < o.relay_settle_max_s) {
    round();
  }

  // Measure.
  const size_t R = o.receivers;
  std::vector<uint64_t> socket0(R), state0(R);
  for (size_t k = 0; k < R; ++k) {
    socket0[k] = world.ReceivedBytes(k + 1);
    state0[k] = world.client(k + 1).state_bytes_received();
    receivers[k]->measuring = true;
  }
  const RelayFigures a = world.relay.Read();
  const double m0 = now();
  std::vector<Vec3f> prev(box_index.size());
  double prev_steps = -1, next_moving = m0;
  std::vector<double> moving;
  const Client& watcher = world.client(1);
  while (now() < m0 + o.duration_s) {
    round();
    if (now() < next_moving) continue;
    next_moving += 0.5;
    std::vector<Vec3f> pos(box_index.size());
    for (const auto& [id, k] : box_index) {
      if (const RemoteEntity* e = watcher.FindEntity(id); e != nullptr) pos[k] = e->state.position;
    }
    const double steps = sim_steps();
    if (prev_steps >= 0 && steps > prev_steps) {
      const double sim_dt = (steps - prev_steps) * dt;
      size_t count = 0;
      for (size_t k = 0; k < pos.size(); ++k) count += Dist(pos[k], prev[k]) / sim_dt > o.moving_speed_mps;
      moving.push_back(static_cast<double>(count) / static_cast<double>(pos.size()));
    }
    prev = std::move(pos);
    prev_steps = steps;
  }
  const RelayFigures b = world.relay.Read();
  const double elapsed = now() - m0;
  if (!world.AllConnected()) {
    std::fprintf(stderr, "\nmultiobject: %u objects: a client lost its connection; results void\n", n);
    return;
  }
  double socket_total = 0, state_total = 0, updates = 0, events = 0;
  for (size_t k = 0; k < R; ++k) {
    socket_total += static_cast<double>(world.ReceivedBytes(k + 1) - socket0[k]);
    state_total += static_cast<double>(world.client(k + 1).state_bytes_received() - state0[k]);
    updates += static_cast<double>(receivers[k]->updates);
    events += static_cast<double>(receivers[k]->events);
  }
  world.DisconnectAll();
  const double per = static_cast<double>(R) * elapsed;
  const bool metrics = a.ok && b.ok;
  // Egress counts the host's connection too (SetExternalWindowRates); the in-process run counts
  // the receivers' connections only: the two agree within the host's acks.
  SetExternalWindowRates(r, a, b, R, elapsed, socket_total, dt);
  const double relay_bytes = metrics ? b.bytes_sent - a.bytes_sent : kUnknown;
  r->updates_per_s_per_client = updates / per;
  r->bytes_per_update = updates > 0 ? relay_bytes / updates : kUnknown;
  r->state_mbit_per_s_per_client = state_total * 8 / 1e6 / per;
  r->events_per_s_per_client = events / per;
  double sum = 0;
  for (double x : moving) sum += x;
  r->relay_moving_fraction = moving.empty() ? 0 : sum / static_cast<double>(moving.size());
  r->relay_moving_fraction_min = moving.empty() ? 0 : *std::min_element(moving.begin(), moving.end());
  r->external_cpu_cores = metrics ? (b.cpu_s - a.cpu_s) / (b.t - a.t) : kUnknown;
}

}  // namespace edgephys::loadgen
