#include "loadgen/multiobject.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <thread>
#include <unordered_map>

#include "client/interpolation.h"
#include "client/snapshot_buffer.h"
#include "loadgen/paper_figures.h"
#include "loadgen/relay_window_result.h"
#include "loadgen/stats.h"
#include "loadgen/scenes/scenes.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"

namespace edgephys::loadgen {

// ---------------------------------------------------------------------------------------------
// The scenario

physics::MultiObjectParams MultiObjectSceneParams(const MultiObjectOptions& o, uint32_t n) {
  physics::MultiObjectParams p;
  p.num_objects = static_cast<int>(n);
  p.seed = o.seed;
  p.layers = o.layers;
  p.stirrer_angular_speed = o.stirrer_angular_speed;
  p.stirrer_reach = o.stirrer_reach;
  p.stirrer_center_y = o.stirrer_center_y;
  p.stirrer_half_height = o.stirrer_half_height;
  return p;
}

namespace {

// Recent relay states kept per box (at 60 Hz: 1.07 s): the "vs sent" error looks for the state
// a received one was sent from among them, and a key sample at the kink (format 14) may be up
// to a max interval old.
constexpr size_t kRing = 64;
constexpr uint32_t F(schema::EntityFlags f) { return static_cast<uint32_t>(f); }

void Bench(const MultiObjectOptions& o, uint32_t n, MultiObjectResult* r) {
  physics::MultiObjectParams p = MultiObjectSceneParams(o, n);
  p.config.sleep_linear_threshold = o.sleep_threshold;
  p.config.sleep_angular_threshold = o.sleep_threshold;
  p.config.rest_freeze = o.rest_freeze;
  physics::PhysSMultiObjectScene phys(p);
  physics::RawBulletMultiObjectScene raw(p);
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < o.bench_warmup_steps; ++i) {
    phys.Step();
    raw.Step();
    if (o.progress && i % 10 == 0) {
      std::fprintf(stderr, "\r  %6u objects  standalone: settling %d / %d steps (%.0f s)   ", n, i,
                   o.bench_warmup_steps, Seconds(std::chrono::steady_clock::now() - t0));
    }
  }
  std::vector<double> phys_ms, raw_ms, phys_moving, raw_moving;
  const auto m0 = std::chrono::steady_clock::now();
  auto time_step = [](auto& scene) {
    const auto a = std::chrono::steady_clock::now();
    scene.Step();
    return Seconds(std::chrono::steady_clock::now() - a) * 1000.0;
  };
  for (int i = 0; i < o.bench_steps; ++i) {
    if (i >= o.bench_min_steps && Seconds(std::chrono::steady_clock::now() - m0) > o.bench_max_s) break;
    if (i % 2 == 0) {
      phys_ms.push_back(time_step(phys));
      raw_ms.push_back(time_step(raw));
    } else {
      raw_ms.push_back(time_step(raw));
      phys_ms.push_back(time_step(phys));
    }
    if (i % 10 == 0) {
      const float v = static_cast<float>(o.moving_speed_mps);
      phys_moving.push_back(static_cast<double>(phys.MovingBoxes(v)) / n);
      raw_moving.push_back(static_cast<double>(raw.MovingBoxes(v)) / n);
      if (o.progress) {
        std::fprintf(stderr, "\r  %6u objects  standalone: step %d / %d (%.0f s)               ", n,
                     i, o.bench_steps, Seconds(std::chrono::steady_clock::now() - m0));
      }
    }
  }
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0.0 : s / static_cast<double>(v.size());
  };
  auto min = [](const std::vector<double>& v) {
    return v.empty() ? 0.0 : *std::min_element(v.begin(), v.end());
  };
  r->bench_steps = static_cast<int>(phys_ms.size());
  r->step_ms_median = Median(phys_ms);
  r->step_ms_p99 = Percentile(phys_ms, 99);
  r->raw_bullet_step_ms_median = Median(raw_ms);
  r->raw_bullet_step_ms_p99 = Percentile(raw_ms, 99);
  r->step_ratio = r->raw_bullet_step_ms_median > 0 ? r->step_ms_median / r->raw_bullet_step_ms_median : 0;
  r->moving_fraction = mean(phys_moving);
  r->moving_fraction_min = min(phys_moving);
  r->raw_moving_fraction = mean(raw_moving);
  r->raw_moving_fraction_min = min(raw_moving);
}

struct BoxTable {
  std::unordered_map<uint32_t, size_t> index;  // entity id -> box index
  std::vector<std::array<Vec3f, kRing>> ring;  // relay's recent positions per box
  std::vector<uint32_t> count;
};

// What a receiver displays, against the truth: a sample of boxes gets a jitter buffer each (the
// SDK's adaptive playout), and every `period` the pose interpolated at the playout time is
// compared with the relay's state at that same relay time (linear between the relay's
// recorded states, which change at PhyS's 60 Hz). This is the accuracy a lower send rate
// costs; the quantisation error alone is the "vs sent" error.
struct DisplayProbe {
  static constexpr size_t kMaxBoxes = 128;
  struct Truth {
    double t;  // relay time, s
    Vec3f p;
    Quatf q;
  };
  std::unordered_map<size_t, size_t> slot;  // box index -> probe slot
  std::vector<SnapshotBuffer> buffers;
  std::vector<std::vector<Truth>> truth;
  // The same states at the time PhyS computed them for (Entity::state_time) rather than when
  // the relay got them: the second yardstick (display_err_state_*).
  std::vector<std::vector<Truth>> truth_state;
  std::vector<double> state_errors;
  std::vector<double> lerp_errors, hermite_errors, rot_errors_deg, delays_ms, playout_ms;
  // The same arrivals in jitter buffers at the room's playout held to a limit
  // (MultiObjectOptions::playout_limit_s; CapPlayoutDelay: edgephys_client_set_max_playout_delay),
  // drawn with the same method: the third yardstick (display_err_adaptive_*). Without a limit
  // it is the first.
  std::vector<SnapshotBuffer> adaptive_buffers;
  SnapshotBufferConfig adaptive_config;
  SampleOptions adaptive_options;
  std::vector<double> adaptive_errors, adaptive_playout_ms;
  double local_now = 0;
  SampleOptions sample_options;

  // `min_delay_s` >= 0: a fixed playout delay instead of the SDK's adaptive one.
  void Init(size_t boxes, double min_delay_s, double playout_limit_s) {
    const size_t n = std::min(boxes, kMaxBoxes);
    SnapshotBufferConfig config;
    if (min_delay_s >= 0) {
      config.interval_multiplier = 0;
      config.min_delay_s = min_delay_s;
      config.max_delay_s = std::max(config.max_delay_s, config.min_delay_s);
    }
    adaptive_config = CapPlayoutDelay(config, playout_limit_s);
    buffers.assign(n, SnapshotBuffer(config));
    adaptive_buffers.assign(n, SnapshotBuffer(adaptive_config));
    truth.assign(n, {});
    truth_state.assign(n, {});
    for (size_t i = 0; i < n; ++i) slot[i * boxes / n] = i;
  }
  void RecordTruth(size_t box, double relay_time, double state_time, const EntityState& s) {
    auto it = slot.find(box);
    if (it == slot.end()) return;
    truth[it->second].push_back({relay_time, s.position, s.rotation});
    auto& h = truth_state[it->second];
    if (h.empty() || state_time > h.back().t) h.push_back({state_time, s.position, s.rotation});
  }
  void OnReceived(size_t box, const RemoteEntity& e) {
    auto it = slot.find(box);
    if (it == slot.end()) return;
    Snapshot s{.sender_time_s = e.state_time_ms / 1000.0,
               .position = e.state.position,
               .rotation = e.state.rotation};
    (void)buffers[it->second].Insert(s, local_now);
    (void)adaptive_buffers[it->second].Insert(s, local_now);
  }
  // At the start: what the receiver holds for each probed box (a box at rest may get nothing
  // more), and the relay's truth then (recorded again only when it changes).
  void Seed(const std::vector<uint32_t>& ids, const Client& receiver,
            const std::vector<const Entity*>& relay, double relay_now) {
    for (const auto& [box, i] : slot) {
      RecordTruth(box, relay_now, std::min(relay_now, relay[box]->state_time), relay[box]->state);
      const RemoteEntity* e = receiver.FindEntity(ids[box]);
      if (e == nullptr || !e->has_state) continue;
      // Received long ago: as if it had arrived 1 ms after it was sent (relay and receivers
      // share this process's clock), so that its age does not count as arrival jitter.
      const double saved = local_now;
      local_now = std::min(local_now, e->state_time_ms / 1000.0 + 0.001);
      OnReceived(box, *e);
      local_now = saved;
    }
  }
  // The relay's pose at relay time t (false if t is outside what was recorded).
  bool TruthAt(size_t i, double t, Pose* out) const { return TruthIn(truth[i], t, out); }
  static bool TruthIn(const std::vector<Truth>& h, double t, Pose* out) {
    auto it = std::lower_bound(h.begin(), h.end(), t,
                               [](const Truth& a, double v) { return a.t < v; });
    if (it == h.begin()) return false;
    if (it == h.end()) {  // unchanged since the last record
      out->position = h.back().p;
      out->rotation = h.back().q;
      return true;
    }
    const Truth& b = *it;
    const Truth& a = *(it - 1);
    const float u = b.t > a.t ? static_cast<float>((t - a.t) / (b.t - a.t)) : 1.f;
    out->position = {a.p.x + (b.p.x - a.p.x) * u, a.p.y + (b.p.y - a.p.y) * u,
                     a.p.z + (b.p.z - a.p.z) * u};
    out->rotation = FromEigen(Slerp(ToEigen(a.q), ToEigen(b.q), u));
    return true;
  }
  // A buffer with one state (a box at rest since the seed) has no clock of its own: it is
  // shown at the relay time the others are (the lowest clock offset, the median delay). Sets
  // *offset to that lowest offset; false when no buffer has a clock yet.
  static bool SharedRender(std::vector<SnapshotBuffer>& set, double now, double* offset,
                           double* render) {
    *offset = 1e9;
    std::vector<double> delays;
    for (SnapshotBuffer& b : set) {
      if (b.size() < 2) continue;
      *offset = std::min(*offset, b.clock_offset_s());
      (void)b.RenderTime(now);
      delays.push_back(b.current_delay_s());
    }
    if (delays.empty()) return false;
    *render = now - *offset - Percentile(delays, 50);
    return true;
  }
  void Sample(double now) {
    double offset = 0, shared_render = 0, adaptive_offset = 0, adaptive_shared = 0;
    if (!SharedRender(buffers, now, &offset, &shared_render)) return;
    // The same arrivals, so the adaptive buffers have clocks too.
    (void)SharedRender(adaptive_buffers, now, &adaptive_offset, &adaptive_shared);
    for (size_t i = 0; i < buffers.size(); ++i) {
      SnapshotBuffer& b = buffers[i];
      if (b.empty()) continue;
      const double render = b.size() >= 2 ? b.RenderTime(now) : shared_render;
      Pose want;
      if (!TruthAt(i, render, &want)) continue;
      const Pose lerp = edgephys::Sample(b, render, Interpolator::kLerpSlerp, sample_options);
      const Pose hermite = edgephys::Sample(b, render, Interpolator::kHermite, sample_options);
      const Pose& shown = lerp;
      lerp_errors.push_back(Dist(shown.position, want.position));
      Pose want_state;
      if (TruthIn(truth_state[i], render, &want_state)) {
        state_errors.push_back(Dist(shown.position, want_state.position));
      }
      hermite_errors.push_back(Dist(hermite.position, want.position));
      rot_errors_deg.push_back(Compare(shown, want).rot_deg);
      delays_ms.push_back((b.newest().sender_time_s - render) * 1000.0);
      playout_ms.push_back((now - offset - render) * 1000.0);
      SnapshotBuffer& adaptive = adaptive_buffers[i];
      const double adaptive_render = adaptive.size() >= 2 ? adaptive.RenderTime(now) : adaptive_shared;
      Pose adaptive_want;
      if (!adaptive.empty() && TruthAt(i, adaptive_render, &adaptive_want)) {
        const Pose adaptive_shown =
            edgephys::Sample(adaptive, adaptive_render, Interpolator::kLerpSlerp, adaptive_options);
        adaptive_errors.push_back(Dist(adaptive_shown.position, adaptive_want.position));
        adaptive_playout_ms.push_back((now - adaptive_offset - adaptive_render) * 1000.0);
      }
    }
  }
};

class BoxReceiver : public ClientListener {
 public:
  explicit BoxReceiver(const BoxTable* boxes) : boxes_(boxes) {}
  void OnEntityUpdated(const RemoteEntity& e) override {
    if (!measuring && probe == nullptr) return;
    auto it = boxes_->index.find(e.id);
    if (it == boxes_->index.end()) return;
    if (probe != nullptr) probe->OnReceived(it->second, e);
    if (!measuring) return;
    ++updates;
    const size_t k = it->second;
    const size_t n = std::min<size_t>(boxes_->count[k], kRing);
    if (n == 0) return;
    double best = 1e9;
    for (size_t j = 0; j < n; ++j) best = std::min(best, Dist(e.state.position, boxes_->ring[k][j]));
    sent_errors.push_back(best);
  }
  void OnPhysicsEvent(uint8_t, uint32_t, uint32_t) override {
    if (measuring) ++events;
  }
  bool measuring = false;
  DisplayProbe* probe = nullptr;  // receiver 0 only
  uint64_t updates = 0, events = 0;
  std::vector<double> sent_errors;

 private:
  const BoxTable* boxes_;
};

void RelayRun(const MultiObjectOptions& o, uint32_t n, MultiObjectResult* r) {
  physics::MultiObjectParams p = MultiObjectSceneParams(o, n);
  const double dt = p.config.fixed_dt;

  RelayConfig config =
      BenchmarkRelayConfig(o.receivers, n + 64, o.position_step_m, o.rotation_bound_deg);
  if (o.position_threshold_m >= 0) {
    config.room_defaults.replication.position_threshold_m = o.position_threshold_m;
  }
  if (o.rotation_threshold_deg >= 0) {
    config.room_defaults.replication.rotation_threshold_deg = o.rotation_threshold_deg;
  }
  if (o.ambient_hz > 0) config.room_defaults.replication.ambient_hz = o.ambient_hz;
  ReplicationConfig& rep = config.room_defaults.replication;
  rep.shared_encoding = o.shared_encoding;
  config.physics.max_substeps = o.relay_max_substeps;
  config.physics.sleep_linear_threshold = o.sleep_threshold;
  config.physics.sleep_angular_threshold = o.sleep_threshold;
  config.physics.rest_freeze = o.rest_freeze;
  config.connection.max_pending_reliable_bytes = std::max<size_t>(
      config.connection.max_pending_reliable_bytes, static_cast<size_t>(n) * 1024);

  BoxTable boxes;
  auto [receivers, listeners] = MakeReceiverSet<BoxReceiver>(o.receivers, nullptr, &boxes);
  ClientConfig host_config;
  host_config.publish_rate_hz = 120;  // the stirrer's pose reaches PhyS with little delay
  LoopbackRoom world(config, "multiobject", o.receivers + 1, host_config, listeners);
  if (!world.ConnectAndJoin(5.0)) {
    std::fprintf(stderr, "multiobject: clients failed to connect/join\n");
    return;
  }
  Client& host = world.client(0);
  RelayCounters& counters = world.counters();

  // The host dissects the scene: static floor and walls, the kinematic stirrer it drives, and
  // the boxes handed to PhyS.
  const double spawn_start = world.Now();
  uint32_t stirrer = 0;
  std::vector<uint32_t> box_ids;
  const auto specs = physics::MultiObjectSpecs(p);
  for (const EntitySpec& s : specs) {
    auto id = host.Spawn(OffloadedSpawn(s));
    if (!id.ok()) {
      std::fprintf(stderr, "multiobject: spawn failed: %s\n", std::string(id.status().message()).c_str());
      return;
    }
    if (s.id == physics::kSceneStirrerId) stirrer = *id;
    if (s.id >= physics::kSceneFirstBoxId) {
      boxes.index[*id] = box_ids.size();
      box_ids.push_back(*id);
    }
  }
  boxes.ring.resize(box_ids.size());
  boxes.count.assign(box_ids.size(), 0);
  DisplayProbe probe;
  probe.Init(box_ids.size(), o.playout_min_delay_s, o.playout_limit_s);

  auto drive_stirrer = [&] {
    Vec3f pos;
    Quatf rot;
    const double sim_t = static_cast<double>(RelayCounters::Get(counters.physics_steps)) * dt;
    physics::StirrerPose(p, sim_t, &pos, &rot);
    (void)host.PublishTransform(stirrer, pos, rot);
  };
  auto round = [&] {
    drive_stirrer();
    world.Step();
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  };

  // Everyone has the whole scene.
  double last_check = -1;
  bool spawned = false;
  while (world.Now() - spawn_start < 120.0) {
    round();
    if (world.Now() - last_check < 0.2) continue;
    last_check = world.Now();
    const Room* room = world.room();
    if (room == nullptr || room->entities().size() < specs.size()) continue;
    bool all = true;
    for (size_t c = 1; c < world.client_count() && all; ++c) {
      size_t have = 0;
      for (const auto& [id, e] : world.client(c).entities()) have += e.spawned ? 1 : 0;
      all = have >= specs.size();
    }
    if (all) {
      spawned = true;
      break;
    }
    if (o.progress) {
      std::fprintf(stderr, "\r  %6u objects  relay: spawning (%zu in room)             ", n,
                   room->entities().size());
    }
  }
  if (!spawned) {
    for (size_t c = 0; c < world.client_count(); ++c) {
      std::fprintf(stderr, "multiobject: client %zu state %d disconnect reason %d\n", c,
                   static_cast<int>(world.client(c).state()),
                   static_cast<int>(world.client(c).disconnect_reason()));
    }
    std::fprintf(stderr, "\nmultiobject: the scene did not reach every client within 120 s\n");
    return;
  }
  r->spawn_s = world.Now() - spawn_start;

  // Cache the relay's entities (node-based map: stable while they exist).
  const Room* room = world.room();
  std::vector<const Entity*> relay_boxes(box_ids.size());
  for (size_t k = 0; k < box_ids.size(); ++k) relay_boxes[k] = &room->entities().at(box_ids[k]);
  std::vector<uint32_t> seen_version(box_ids.size(), 0);

  // Settle.
  if (o.progress) std::fprintf(stderr, "\r  %6u objects  relay: settling                     ", n);
  RunPhysicsSteps(world, static_cast<uint64_t>(o.relay_settle_steps), o.relay_settle_max_s, round);

  // Measure.
  const size_t R = o.receivers;
  std::vector<uint64_t> state_bytes0(R);
  for (size_t k = 0; k < R; ++k) {
    state_bytes0[k] = world.client(k + 1).state_bytes_received();
    receivers[k]->measuring = true;
  }
  WindowMeter meter;
  meter.Start(world, R);
  const double t0 = world.Now();
  const double t_end = t0 + o.duration_s;
  double next_error = t0, next_moving = t0, last_progress = 0;
  uint64_t last_scanned_steps = 0;
  std::vector<double> same_errors, moving_samples;
  std::vector<Vec3f> prev_pos(box_ids.size());
  uint64_t prev_steps = 0;
  bool have_prev = false;
  const Client& watcher = world.client(1);
  // Warm the probe's jitter buffers for a second before sampling them.
  probe.local_now = world.Now();
  probe.Seed(box_ids, world.client(1), relay_boxes, world.Now());
  receivers[0]->probe = &probe;
  double probe_from = t0 + 1.0, next_probe = probe_from;
  while (world.Now() < t_end) {
    drive_stirrer();
    const double relay_now = world.Now();
    world.UpdateRelay();
    if (world.room() == nullptr || world.room()->size() < world.client_count() ||
        world.room()->entities().size() < specs.size()) {
      std::fprintf(stderr, "\nmultiobject: %u objects: a client left the room during the measurement\n", n);
      break;  // cached entity pointers may dangle now
    }
    const uint64_t steps = RelayCounters::Get(counters.physics_steps);
    if (steps != last_scanned_steps) {  // record what PhyS produced (and the relay may send)
      last_scanned_steps = steps;
      for (size_t k = 0; k < relay_boxes.size(); ++k) {
        if (relay_boxes[k]->version == seen_version[k]) continue;
        seen_version[k] = relay_boxes[k]->version;
        boxes.ring[k][boxes.count[k]++ % kRing] = relay_boxes[k]->state.position;
        probe.RecordTruth(k, relay_now, relay_boxes[k]->state_time, relay_boxes[k]->state);
      }
    }
    probe.local_now = world.Now();
    world.UpdateClients();
    const double now = world.Now();
    if (now >= next_probe) {
      next_probe += 0.05;
      if (now >= probe_from) probe.Sample(now);
    }
    if (now >= next_error) {  // receivers' latest vs the relay's state, same moment
      next_error += 0.1;
      for (size_t c = 1; c < world.client_count(); ++c) {
        for (size_t k = 0; k < box_ids.size(); ++k) {
          const RemoteEntity* e = world.client(c).FindEntity(box_ids[k]);
          if (e == nullptr || !e->spawned) continue;
          same_errors.push_back(Dist(e->state.position, relay_boxes[k]->state.position));
        }
      }
    }
    if (now >= next_moving) {  // moving share from the states the first receiver holds
      next_moving += 0.5;
      std::vector<Vec3f> pos(box_ids.size());
      for (size_t k = 0; k < box_ids.size(); ++k) {
        const RemoteEntity* e = watcher.FindEntity(box_ids[k]);
        if (e != nullptr) pos[k] = e->state.position;
      }
      if (have_prev && steps > prev_steps) {
        const double sim_dt = static_cast<double>(steps - prev_steps) * dt;
        size_t moving = 0;
        for (size_t k = 0; k < pos.size(); ++k) {
          if (Dist(pos[k], prev_pos[k]) / sim_dt > o.moving_speed_mps) ++moving;
        }
        moving_samples.push_back(static_cast<double>(moving) / static_cast<double>(pos.size()));
      }
      if (!have_prev || steps > prev_steps) {
        prev_pos = std::move(pos);
        prev_steps = steps;
        have_prev = true;
      }
    }
    if (o.progress && now - last_progress >= 0.5) {
      last_progress = now;
      std::fprintf(stderr, "\r  %6u objects  relay: measuring %4.1f / %.1f s             ", n,
                   now - t0, o.duration_s);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  const WindowMeter::Totals window = meter.Finish(world);
  const double elapsed = window.elapsed_s;
  for (size_t c = 0; c < world.client_count(); ++c) {
    if (world.client(c).state() != ClientState::kConnected) {
      std::fprintf(stderr, "\nmultiobject: %u objects: client %zu lost its connection (reason %d); "
                   "results of this size are void\n", n, c,
                   static_cast<int>(world.client(c).disconnect_reason()));
      return;
    }
  }
  const double relay_total = window.relay_bytes;
  double state_total = 0, updates = 0, events = 0;
  std::vector<double> sent;
  for (size_t k = 0; k < R; ++k) {
    state_total += static_cast<double>(world.client(k + 1).state_bytes_received() - state_bytes0[k]);
    updates += static_cast<double>(receivers[k]->updates);
    events += static_cast<double>(receivers[k]->events);
    sent.insert(sent.end(), receivers[k]->sent_errors.begin(), receivers[k]->sent_errors.end());
  }
  const double per = static_cast<double>(R) * elapsed;
  SetRelayWindowRates(r, window, R, dt);
  r->updates_per_s_per_client = updates / per;
  r->bytes_per_update = updates > 0 ? relay_total / updates : 0;
  r->state_mbit_per_s_per_client = state_total * 8 / 1e6 / per;
  r->events_per_s_per_client = events / per;
  r->relay_moving_fraction = moving_samples.empty() ? 0 : [&] {
    double s = 0;
    for (double x : moving_samples) s += x;
    return s / static_cast<double>(moving_samples.size());
  }();
  r->relay_moving_fraction_min =
      moving_samples.empty() ? 0 : *std::min_element(moving_samples.begin(), moving_samples.end());
  r->pos_err_max_m = Max(same_errors);
  r->pos_err_p99_m = Percentile(same_errors, 99);
  r->pos_err_sent_max_m = Max(sent);
  r->pos_err_sent_p99_m = Percentile(sent, 99);
  r->error_samples = same_errors.size();
  SetP50P99(probe.lerp_errors, &r->display_err_p50_m, &r->display_err_p99_m);
  SetP50P99(probe.state_errors, &r->display_err_state_p50_m, &r->display_err_state_p99_m);
  SetP50P99(probe.hermite_errors, &r->display_err_hermite_p50_m, &r->display_err_hermite_p99_m);
  SetP50P99(probe.adaptive_errors, &r->display_err_adaptive_p50_m, &r->display_err_adaptive_p99_m);
  r->display_adaptive_playout_ms_median = Percentile(probe.adaptive_playout_ms, 50);
  r->display_delay_ms_median = Percentile(probe.delays_ms, 50);
  r->display_playout_ms_median = Percentile(probe.playout_ms, 50);
  SetP50P99(probe.rot_errors_deg, &r->display_rot_err_p50_deg, &r->display_rot_err_p99_deg);
  r->display_samples = probe.lerp_errors.size();
}

}  // namespace

std::vector<MultiObjectResult> RunMultiObject(const MultiObjectOptions& o) {
  std::vector<MultiObjectResult> results;
  for (uint32_t n : o.objects) {
    MultiObjectResult r;
    r.objects = n;
    r.paper_mbit_per_s = PaperObjMbitPerS(n);
    if (o.bench) Bench(o, n, &r);
    if (o.relay && o.external.enabled()) {
      ExternalMultiObjectRun(o, n, &r);
    } else if (o.relay) {
      RelayRun(o, n, &r);
    }
    if (o.progress) std::fprintf(stderr, "\r%78s\r", "");
    results.push_back(r);
  }
  return results;
}

}  // namespace edgephys::loadgen
