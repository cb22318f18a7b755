// softbody against an EXTERNAL edgephys-relay (--relay HOST:PORT --secret S): the scene, host
// and receivers of the in-process run over real sockets (loadgen/external_room.h), server-side
// figures from the relay's /metrics. The hands are aimed at the bunnies as the host receives
// them and follow the relay's PhyS step counter; deformation is bunny 0 as the host receives it.
// The particle errors against the relay's own particles need it in-process: null here.
#include <algorithm>
#include <cstdio>
#include <memory>
#include <thread>
#include <unordered_map>

#include "loadgen/external_room.h"
#include "loadgen/loopback_room.h"
#include "loadgen/relay_window_result.h"
#include "loadgen/softbody.h"
#include "loadgen/softbody_scene.h"
#include "loadgen/stats.h"

namespace edgephys::loadgen {
namespace {

struct ExternalSoftReceiver : ClientListener {
  explicit ExternalSoftReceiver(const std::unordered_map<uint32_t, size_t>* index) : bunnies(index) {}
  void OnSoftBodyUpdated(const RemoteEntity& e) override {
    if (measuring && bunnies->count(e.id) != 0) ++updates;
  }
  const std::unordered_map<uint32_t, size_t>* bunnies;
  bool measuring = false;
  uint64_t updates = 0;
};

}  // namespace

void ExternalSoftBodyRun(const SoftBodyOptions& o, uint32_t n, SoftBodyResult* r) {
  r->node_err_max_m = r->node_err_p99_m = r->node_err_sent_max_m = r->node_err_sent_p99_m = kUnknown;
  SoftBodyScene scene = MakeSoftBodyScene(o, n);
  const double dt = 1.0 / 60.0;  // PhysicsConfig::fixed_dt, the relay's default
  std::unordered_map<uint32_t, size_t> bunny_index;
  ExternalSceneRoom<ExternalSoftReceiver> world(o.external, "softbody-" + std::to_string(n),
                                                o.receivers, &bunny_index);
  if (!world.JoinAll(15)) return;
  const auto& receivers = world.receivers;
  Client& host = world.client(0);
  std::vector<uint32_t> bunny_ids, hand_ids;
  for (const EntitySpec& s : scene.specs) {
    auto id = host.Spawn(OffloadedSpawn(s));
    if (!id.ok()) {
      std::fprintf(stderr, "softbody: spawn refused by the relay: %s (its particle budgets: see "
                   "docs/operations.md)\n", std::string(id.status().message()).c_str());
      return;
    }
    if (s.soft_body) {
      bunny_index.emplace(*id, bunny_ids.size());
      bunny_ids.push_back(*id);
    }
    if (s.id >= kFirstHandId) hand_ids.push_back(*id);
  }

  double poke_start = -1;  // relay PhyS step the pokes start at (after settling)
  auto drive_hands = [&] {
    const double steps = world.PhysicsSteps();
    const double sim_t = poke_start >= 0 && steps >= poke_start ? (steps - poke_start) * dt : -1.0;
    scene.PublishHands(host, hand_ids, sim_t);
  };
  auto round = [&] {
    drive_hands();
    world.Update();
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  };
  // Everyone (the host too: it aims the hands) has every bunny with its particles.
  auto has_bunnies = [&](const Client& c) {
    return std::all_of(bunny_ids.begin(), bunny_ids.end(), [&](uint32_t id) {
      const RemoteEntity* e = c.FindEntity(id);
      return e != nullptr && e->spawned && !e->nodes.empty();
    });
  };
  const double spawn_start = world.Now();
  bool ready = false;
  while (!ready && world.Now() - spawn_start < 30.0) {
    round();
    ready = true;
    for (size_t c = 0; c < world.size() && ready; ++c) ready = has_bunnies(world.client(c));
    if (world.host_watch.refused()) {
      std::fprintf(stderr, "softbody: the relay refused the scene: %s (its particle budgets: "
                   "docs/operations.md, \"Room budgets\")\n", world.host_watch.what().c_str());
      return;
    }
  }
  if (!ready) {
    std::fprintf(stderr, "softbody: the scene did not reach every client within 30 s\n");
    return;
  }
  const double settle_from = world.PhysicsSteps(), settle_start = world.Now();
  while (world.PhysicsSteps() - settle_from < o.relay_settle_steps &&
         world.Now() - settle_start < o.relay_settle_max_s) {
    round();
  }
  for (size_t k = 0; k < bunny_ids.size(); ++k) scene.Calibrate(k, host.FindEntity(bunny_ids[k])->nodes);
  poke_start = world.PhysicsSteps();
  while (world.PhysicsSteps() < poke_start + 0.25 / dt && world.Now() - settle_start < 2 * o.relay_settle_max_s) {
    round();
  }

  const size_t R = o.receivers;
  std::vector<uint64_t> socket0(R);
  for (size_t k = 0; k < R; ++k) {
    socket0[k] = world.ReceivedBytes(k + 1);
    receivers[k]->measuring = true;
  }
  const RelayFigures a = world.relay.Read();
  const double m0 = world.Now();
  double next_sample = m0;
  std::vector<double> deformation;
  while (world.Now() < m0 + o.duration_s) {
    round();
    if (world.Now() < next_sample) continue;
    next_sample += 0.1;
    if (const RemoteEntity* e = host.FindEntity(bunny_ids[0]); e != nullptr) {
      deformation.push_back(scene.Deformation(0, e->nodes));
    }
  }
  const RelayFigures b = world.relay.Read();
  const double elapsed = world.Now() - m0;
  if (!world.AllConnected()) {
    std::fprintf(stderr, "softbody: %u bunnies: a client lost its connection; results void\n", n);
    return;
  }
  double socket_total = 0, updates = 0;
  for (size_t k = 0; k < R; ++k) {
    socket_total += static_cast<double>(world.ReceivedBytes(k + 1) - socket0[k]);
    updates += static_cast<double>(receivers[k]->updates);
  }
  world.DisconnectAll();
  SetExternalWindowRates(r, a, b, R, elapsed, socket_total, dt);
  r->soft_updates_per_s_per_client = updates / (static_cast<double>(R) * elapsed);
  r->deformation_min_m = deformation.empty() ? 0 : *std::min_element(deformation.begin(), deformation.end());
  r->deformation_max_m = Max(deformation);
}

}  // namespace edgephys::loadgen
