#include "loadgen/isolation.h"

#include <sched.h>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <future>
#include <memory>
#include <mutex>
#include <thread>
#include <unordered_map>
#include <unordered_set>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "loadgen/loopback_room.h"
#include "loadgen/motion.h"
#include "loadgen/pose_history.h"
#include "loadgen/stats.h"
#include "loadgen/scenes/scenes.h"
#include "protocol/handshake.h"

namespace edgephys::loadgen {
namespace {

using Clock = std::chrono::steady_clock;
constexpr uint32_t kFlag(schema::EntityFlags f) { return static_cast<uint32_t>(f); }
constexpr const char* kRoomA = "isolation-a";
constexpr const char* kRoomB = "isolation-b";
constexpr uint32_t kFirstBPlayer = 1000000;  // B's player ids; A's are 1..users

double RealtimeNow() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

std::unique_ptr<UdpSocket> OpenLoopbackSocket() {
  return std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
}

// One latency sample of A.
struct Sample {
  float t;           // receive time (steady seconds since start)
  float sdk_ms;
  float arrival_ms;
};

class World;

class Bot : public ClientListener {
 public:
  Bot(World* world, uint32_t index) : world_(world), index_(index) {}
  void OnEntityUpdated(const RemoteEntity& e) override;
  void Tick(double now);

  World* world_;
  uint32_t index_;
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<Client> client;
  double start_at = 0;
  bool join_requested = false;
  bool spawned = false;
  uint32_t head = 0, left = 0, right = 0;
  Vec3f home;
  double next_publish = 0;
  PoseHistory right_history;  // right-hand publishes for latency matching
  std::unordered_map<uint32_t, Vec3f> last_seen;
};

class World {
 public:
  explicit World(const IsolationOptions& options) : o(options) {}
  double Now() const { return std::chrono::duration<double>(Clock::now() - start).count(); }
  const IsolationOptions& o;
  Clock::time_point start;
  std::vector<std::unique_ptr<Bot>> bots;
  std::unordered_map<uint32_t, Bot*> right_hand_owner;
  bool measuring = false;
  std::vector<Sample> samples;   // while measuring
  uint64_t hand_updates = 0;     // while measuring, in the current phase
};

Vec3f HandPath(const Bot& b, double t, float side) {
  return AvatarHandPosition(b.home, b.index_, t, side);
}

void Bot::OnEntityUpdated(const RemoteEntity& e) {
  auto it = world_->right_hand_owner.find(e.id);
  if (it == world_->right_hand_owner.end() || it->second == this) return;
  if (index_ % world_->o.measure_every != 0) return;
  const Bot& sender = *it->second;
  Vec3f& last = last_seen[e.id];
  const bool repeat = last.x == e.state.position.x && last.y == e.state.position.y &&
                      last.z == e.state.position.z;
  last = e.state.position;
  if (!world_->measuring || repeat) return;
  ++world_->hand_updates;
  const double now = world_->Now();
  if (const PoseHistory::Publish* sent = sender.right_history.Match(e.state.position)) {
    world_->samples.push_back({static_cast<float>(now), static_cast<float>((now - sent->t) * 1000.0),
                               static_cast<float>((e.arrival_unix_s - sent->unix_s) * 1000.0)});
  }
}

void Bot::Tick(double now) {
  Client& c = *client;
  if (c.state() != ClientState::kConnected || !c.joined()) return;
  if (!spawned) {
    spawned = true;
    AvatarIds avatar;
    (void)SpawnAvatar(c, home, index_, now, &avatar);  // a refusal leaves that id 0 (unused)
    head = avatar.head;
    left = avatar.left;
    right = avatar.right;
    world_->right_hand_owner[right] = this;
    return;
  }
  if (now < next_publish) return;
  next_publish = now + 1.0 / world_->o.publish_hz;
  (void)c.PublishTransform(head, {home.x, 1.6f + 0.05f * std::sin(float(now)), home.z}, {});
  (void)c.PublishTransform(left, HandPath(*this, now, -1.f), {});
  const Vec3f r = HandPath(*this, now, 1.f);
  const double published_unix_s = RealtimeNow();
  (void)c.PublishTransform(right, r, {});
  right_history.Add({.t = now, .unix_s = published_unix_s, .position = r});
}

// Room B on its own thread: the host with the scene, receivers and the late joiner.
class RoomB : public ClientListener {
 public:
  // The late joiner's listener: counts the scene's spawns.
  struct Joiner : ClientListener {
    RoomB* b = nullptr;
    std::unordered_set<uint32_t> seen;
    void OnEntitySpawned(const RemoteEntity& e) override {
      if (b->scene_ids_.count(e.id)) seen.insert(e.id);
    }
  };

  RoomB(const IsolationOptions& o, RelayTarget* relay, Clock::time_point t0)
      : o_(o), relay_(relay), t0_(t0) {
    params_.num_objects = static_cast<int>(o.boxes);
    params_.seed = o.seed;
    joiner_.b = this;
  }

  void Start() { thread_ = std::thread([this] { Run(); }); }
  void Leave() { leave_.store(true); }
  void Stop() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  ~RoomB() { Stop(); }

  // Set by the B thread; read by the main thread after `done_spawning_` / `late_done_`.
  std::atomic<bool> spawned{false};      // every Spawn issued (or failed)
  std::atomic<bool> late_finished{false};  // late joiner complete or timed out
  std::mutex mu;                          // guards the fields below
  bool ok = false;
  std::string error;
  double spawn_send_s = 0;
  std::string thread_policy;  // B's thread's scheduling policy as it ran ("other", "idle")
  bool late_ok = false;
  double late_join_s = kUnknown;
  uint32_t late_spawns = 0;
  uint32_t scene_entities = 0;

 private:
  double Now() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }

  struct Member {
    std::unique_ptr<UdpSocket> socket;
    std::unique_ptr<Client> client;
    bool join_requested = false;
    double join_requested_at = -1;
  };

  void Connect(Member& m, uint32_t player, const ClientConfig& cc, ClientListener* listener) {
    m.socket = OpenLoopbackSocket();
    m.client = std::make_unique<Client>(cc, m.socket.get(), listener);
    (void)m.client->Connect(ToRelayAddress(relay_->endpoint()), relay_->Token(kRoomB, player), Now());
  }
  void Update(Member& m, double now) {
    if (!m.client) return;
    m.client->Update(now);
    if (m.client->state() == ClientState::kConnected && !m.join_requested) {
      (void)m.client->JoinRoom(kRoomB);
      m.join_requested = true;
      m.join_requested_at = now;
    }
  }
  void Fail(const std::string& why) {
    std::lock_guard<std::mutex> lock(mu);
    error = why;
    spawned.store(true);
    late_finished.store(true);
  }

  void Run() {
    if (o_.b_thread_nice > 0) (void)setpriority(PRIO_PROCESS, gettid(), o_.b_thread_nice);
    if (o_.b_thread_idle) {
      sched_param param{};
      if (sched_setscheduler(static_cast<pid_t>(gettid()), SCHED_IDLE, &param) != 0) {
        std::fprintf(stderr, "isolation: B's thread: SCHED_IDLE failed: %s\n", std::strerror(errno));
      }
    }
    {
      const int policy = sched_getscheduler(static_cast<pid_t>(gettid()));
      std::lock_guard<std::mutex> lock(mu);
      thread_policy = policy == SCHED_IDLE ? "idle" : policy == SCHED_OTHER ? "other" : "another";
    }
    ClientConfig host_config;
    host_config.publish_rate_hz = 120;  // the stirrer's pose reaches PhyS with little delay
    host_config.handshake_timeout_s = 10;
    ClientConfig cc;
    cc.handshake_timeout_s = 10;
    // Measurement bots: also against a relay run with --packet-auth false.
    host_config.require_packet_auth = cc.require_packet_auth = false;
    // --b-decode joiner: the host and receivers acknowledge without decoding; the late joiner
    // (which measures) always decodes.
    ClientConfig late_config = cc;
    host_config.decode_states = cc.decode_states = o_.b_decode;
    Member host;
    std::vector<Member> receivers(o_.b_receivers);
    Member late;
    Connect(host, kFirstBPlayer, host_config, nullptr);
    for (uint32_t i = 0; i < o_.b_receivers; ++i) Connect(receivers[i], kFirstBPlayer + 1 + i, cc, nullptr);
    const double b_start = Now();
    uint32_t stirrer = 0;
    bool host_spawned = false;
    double spawns_done_at = -1, late_connected_at = -1;
    bool left = false;
    auto all = [&](auto&& f) {
      f(host);
      for (Member& r : receivers) f(r);
      f(late);
    };
    while (!stop_.load()) {
      const double now = Now();
      if (leave_.load() && !left) {
        all([](Member& m) { if (m.client) m.client->Disconnect(); });
        left = true;
      }
      if (left) {
        std::this_thread::sleep_for(std::chrono::milliseconds(5));
        continue;
      }
      if (!host_spawned && host.client->joined()) {
        host_spawned = true;
        const double t = Now();
        uint32_t n = 0;
        for (const EntitySpec& s : physics::MultiObjectSpecs(params_)) {
          auto id = host.client->Spawn(OffloadedSpawn(s));
          if (!id.ok()) {
            Fail("B host spawn failed: " + std::string(id.status().message()));
            break;
          }
          ++n;
          scene_ids_.insert(*id);
          if (s.id == physics::kSceneStirrerId) stirrer = *id;
        }
        spawns_done_at = Now();
        std::lock_guard<std::mutex> lock(mu);
        if (error.empty()) ok = true;
        spawn_send_s = spawns_done_at - t;
        scene_entities = n;
        spawned.store(true);
      }
      if (!host_spawned && now - b_start > 15) {
        Fail("B host did not join within 15 s");
      }
      if (stirrer != 0) {
        Vec3f pos;
        Quatf rot;
        physics::StirrerPose(params_, now - spawns_done_at, &pos, &rot);
        (void)host.client->PublishTransform(stirrer, pos, rot);
      }
      if (ok && !late.client && now - spawns_done_at >= o_.late_join_delay_s) {
        Connect(late, kFirstBPlayer + 1 + o_.b_receivers, late_config, &joiner_);
        late_connected_at = now;
      }
      all([&](Member& m) { Update(m, now); });
      if (late.client && !late_finished.load()) {
        const bool complete = joiner_.seen.size() >= scene_ids_.size();
        if (complete || now - late_connected_at > o_.late_join_timeout_s) {
          std::lock_guard<std::mutex> lock(mu);
          late_ok = complete && late.join_requested_at >= 0;
          // From the JoinRoom request (after the handshake) to the last spawn's arrival.
          late_join_s = late_ok ? Now() - late.join_requested_at : kUnknown;
          late_spawns = static_cast<uint32_t>(joiner_.seen.size());
          late_finished.store(true);
        }
      }
      std::this_thread::sleep_for(std::chrono::microseconds(200));
    }
    if (!left) all([](Member& m) { if (m.client) m.client->Disconnect(); });
  }

  const IsolationOptions& o_;
  RelayTarget* relay_;
  Clock::time_point t0_;
  physics::MultiObjectParams params_;
  std::unordered_set<uint32_t> scene_ids_;  // B thread only (the joiner runs there too)
  Joiner joiner_;
  std::thread thread_;
  std::atomic<bool> leave_{false}, stop_{false};
};

RelayConfig InProcessConfig(const IsolationOptions& o) {
  RelayConfig config;
  config.secret = "isolation-" + std::to_string(SecureRandom64());
  const uint32_t members = std::max(o.users, o.b_receivers + 2);
  config.max_clients = o.users + o.b_receivers + 64;
  config.room_defaults.capacity = members + 16;
  config.room_defaults.tick_rate_hz = o.tick_rate_hz;
  config.room_defaults.max_entities_per_player = o.boxes + 64;
  config.room_defaults.budgets = RoomBudgets::Unlimited();
  config.limits.max_sessions_per_address = o.users + o.b_receivers + 64;  // all from 127.0.0.1
  config.limits.handshakes_per_s = 100000;
  config.limits.spawns_per_s = 0;  // the B host spawns its scene at once
  config.limits.packets_per_s = 0;
  config.limits.bytes_per_s = 0;
  config.connection.timeout_s = 10;
  config.connection.max_pending_reliable_bytes =
      std::max<size_t>(config.connection.max_pending_reliable_bytes, static_cast<size_t>(o.boxes) * 1024);
  config.physics_threads = std::max<size_t>(1, o.physics_threads);
  if (o.physics_nice >= 0) config.physics_nice = o.physics_nice;
  config.physics_idle = o.physics_idle;
  // As multiobject: one PhyS substep per step, its sleeping thresholds.
  config.physics.max_substeps = 1;
  config.physics.sleep_linear_threshold = 0.1f;
  config.physics.sleep_angular_threshold = 0.1f;
  return config;
}

void FillRelayFigures(const RelayFigures& a, const RelayFigures& b, IsolationPhase* p) {
  p->relay_figures = a.ok && b.ok;
  if (!p->relay_figures) {
    p->egress_bytes_per_s = p->ingress_bytes_per_s = p->relay_cpu = kUnknown;
    p->physics_step_ms_mean = p->physics_steps_per_s = kUnknown;
    return;
  }
  const double dt = std::max(1e-9, b.t - a.t);
  p->egress_bytes_per_s = (b.bytes_sent - a.bytes_sent) / dt;
  p->ingress_bytes_per_s = (b.bytes_received - a.bytes_received) / dt;
  p->relay_cpu = (b.cpu_s - a.cpu_s) / dt;
  const double steps = b.physics_step_count - a.physics_step_count;
  p->physics_step_ms_mean =
      steps > 0 ? (b.physics_step_seconds_sum - a.physics_step_seconds_sum) / steps * 1000 : 0;
  p->physics_steps_per_s = (b.physics_steps - a.physics_steps) / dt;
}

}  // namespace

IsolationResult RunIsolation(const IsolationOptions& o) {
  World world(o);
  world.start = Clock::now();
  const RelayConfig config = InProcessConfig(o);
  std::unique_ptr<RelayTarget> target =
      o.external.enabled() ? std::make_unique<RelayTarget>(o.external, world.start)
                           : std::make_unique<RelayTarget>(config, world.start);
  RelayTarget& relay = *target;

  IsolationResult result;
  result.users = o.users;
  result.boxes = o.boxes;
  for (uint32_t i = 0; i < o.users; ++i) {
    auto bot = std::make_unique<Bot>(&world, i);
    bot->home = {static_cast<float>((i % 32) * 2.0), 0, static_cast<float>((i / 32) * 2.0)};
    bot->start_at = o.ramp_s * i / std::max(1u, o.users);
    world.bots.push_back(std::move(bot));
  }
  ClientConfig cc;
  cc.publish_rate_hz = 240;  // the bot paces itself
  cc.handshake_timeout_s = 10;
  cc.require_packet_auth = false;  // bots: also --packet-auth false
  cc.record_arrival_times = true;

  RoomB room_b(o, &relay, world.start);
  PhysicsBurnProcess burner;
  bool burn_started = false;
  std::string burn_error;
  const uint32_t measuring_bots = (o.users + o.measure_every - 1) / o.measure_every;
  // Per phase, what the A thread records at its bounds; the percentiles (sorts of ~10^5..10^6
  // samples) and the relay's figures (a /metrics scrape, on its own thread) are worked out after
  // the run, so a phase change never stalls A's bots (it showed as a 150-250 ms spike in A's SDK
  // latency at the start of with_b).
  struct PhaseWork {
    size_t first = 0, last = 0;  // world.samples
    uint64_t hand_updates = 0;
    std::vector<double> pass_ms;
    std::future<RelayFigures> begin, end;
  };
  std::vector<PhaseWork> work;
  auto read_async = [&relay] { return std::async(std::launch::async, [&relay] { return relay.Read(); }); };
  auto begin_phase = [&](const char* name, double now) {
    IsolationPhase p;
    p.name = name;
    p.start_s = now;
    result.phases.push_back(p);
    work.emplace_back();
    work.back().first = world.samples.size();
    work.back().begin = read_async();
    world.hand_updates = 0;
    world.measuring = true;
  };
  auto end_phase = [&](double now) {
    result.phases.back().end_s = now;
    world.measuring = false;
    work.back().last = world.samples.size();
    work.back().hand_updates = world.hand_updates;
    work.back().end = read_async();
  };
  auto finish_phases = [&] {
    for (size_t k = 0; k < work.size() && k < result.phases.size(); ++k) {
      IsolationPhase& p = result.phases[k];
      PhaseWork& w = work[k];
      std::vector<double> sdk, arr;
      for (size_t i = w.first; i < w.last; ++i) {
        sdk.push_back(world.samples[i].sdk_ms);
        arr.push_back(world.samples[i].arrival_ms);
      }
      p.samples = sdk.size();
      SetP50P99(sdk, &p.latency_ms_p50, &p.latency_ms_p99);
      SetP50P99(arr, &p.arrival_latency_ms_p50, &p.arrival_latency_ms_p99);
      const double expected = measuring_bots * (o.users > 0 ? o.users - 1.0 : 0.0) * o.publish_hz *
                              (p.end_s - p.start_s);
      p.delivered_fraction = expected > 0 ? w.hand_updates / expected : 0;
      p.bot_pass_ms_p99 = Percentile(w.pass_ms, 99);
      RelayFigures a = w.begin.get();
      RelayFigures b = w.end.valid() ? w.end.get() : RelayFigures{};
      for (const RelayFigures* f : {&a, &b}) {
        if (!f->ok) ++result.metrics_failures, result.metrics_error = f->error;
      }
      FillRelayFigures(a, b, &p);
    }
  };

  // The schedule: A ramps up, settles 1 s, then the phases.
  const double alone_at = o.ramp_s + 1.0;
  enum { kRamp, kAlone, kWithB, kAfter, kDone } phase = kRamp;
  double phase_at = 0;
  bool b_started = false;
  // Hard bound on the whole run: ramp, three phases, the B spawn and the late joiner's wait.
  const double hard_end = alone_at + 3 * o.phase_s + o.late_join_delay_s + o.late_join_timeout_s + 60;
  double next_progress = 1;
  while (phase != kDone) {
    const double now = world.Now();
    if (now > hard_end) {
      if (world.measuring) end_phase(now);
      break;
    }
    switch (phase) {
      case kRamp:
        if (now >= alone_at) begin_phase("alone", now), phase = kAlone, phase_at = now;
        break;
      case kAlone:
        if (now - phase_at >= o.phase_s) {
          end_phase(now);
          if (o.b_burn) {
            burn_started = burner.Start({.boxes = o.boxes, .seconds = o.phase_s + 60, .nice = o.burn_nice, .seed = o.seed},
                                        &burn_error);
          } else {
            room_b.Start();
            b_started = true;
          }
          begin_phase("with_b", now), phase = kWithB, phase_at = now;
        }
        break;
      case kWithB:
        if (now - phase_at >= o.phase_s && (o.b_burn || room_b.late_finished.load())) {
          end_phase(now);
          if (burn_started) {
            PhysicsBurnResult burned;
            result.b_ok = burner.Stop(&burned, &burn_error);
            result.burn_steps = burned.steps;
            result.burn_step_ms_mean = burned.step_ms_mean;
            burn_started = false;
          }
          if (o.after_phase) {
            if (b_started) room_b.Leave();
            begin_phase("after", now), phase = kAfter, phase_at = now;
          } else {
            phase = kDone;
          }
        }
        break;
      case kAfter:
        if (now - phase_at >= o.phase_s) end_phase(now), phase = kDone;
        break;
      case kDone:
        break;
    }
    for (auto& b : world.bots) {
      if (!b->client) {
        if (now < b->start_at) continue;
        b->socket = OpenLoopbackSocket();
        b->client = std::make_unique<Client>(cc, b->socket.get(), b.get());
        (void)b->client->Connect(ToRelayAddress(relay.endpoint()), relay.Token(kRoomA, b->index_ + 1), now);
      }
      b->Tick(now);
      b->client->Update(now);
      if (b->client->state() == ClientState::kConnected && !b->join_requested) {
        (void)b->client->JoinRoom(kRoomA);
        b->join_requested = true;
      }
    }
    if (world.measuring) work.back().pass_ms.push_back((world.Now() - now) * 1000.0);
    if (o.progress && now >= next_progress) {
      next_progress += 1;
      const char* names[] = {"ramp", "alone", "with_b", "after", "done"};
      std::fprintf(stderr, "\r  isolation: t=%5.1f phase=%-6s samples=%zu ", now, names[phase],
                   world.samples.size());
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  if (o.progress) std::fprintf(stderr, "\n");
  finish_phases();
  for (auto& b : world.bots) result.connected += b->client && b->client->joined();
  if (b_started) room_b.Stop();
  if (burn_started) burner.Stop();  // the run ended early (hard bound)
  // Leave the relay clean (an external one keeps serving: no traffic to bots that are gone).
  for (auto& b : world.bots) {
    if (b->client) b->client->Disconnect();
  }
  if (o.b_burn) {
    result.b_error = burn_error;
  } else {
    std::lock_guard<std::mutex> lock(room_b.mu);
    result.b_ok = room_b.ok;
    result.b_error = b_started ? room_b.error : "B never started";
    result.b_spawn_send_s = room_b.spawn_send_s;
    result.late_join_ok = room_b.late_ok;
    result.b_thread_policy = room_b.thread_policy;
    result.late_join_s = room_b.late_join_s;
    result.late_join_spawns = room_b.late_spawns;
    result.scene_entities = room_b.scene_entities;
  }

  // Ratios of with_b to alone.
  const IsolationPhase* alone = nullptr;
  const IsolationPhase* with_b = nullptr;
  for (const IsolationPhase& p : result.phases) {
    if (p.name == "alone") alone = &p;
    if (p.name == "with_b") with_b = &p;
  }
  if (alone && with_b && alone->samples > 0 && with_b->samples > 0) {
    auto ratio = [](double a, double b) { return b > 0 ? a / b : kUnknown; };
    result.p99_ratio = ratio(with_b->latency_ms_p99, alone->latency_ms_p99);
    result.arrival_p99_ratio = ratio(with_b->arrival_latency_ms_p99, alone->arrival_latency_ms_p99);
  }

  // The latency series in bins.
  if (!world.samples.empty() && o.bin_s > 0) {
    std::vector<std::vector<double>> sdk, arr;
    const double t0 = result.phases.empty() ? 0 : result.phases.front().start_s;
    for (const Sample& s : world.samples) {
      const size_t bin = static_cast<size_t>(std::max(0.0, (s.t - t0) / o.bin_s));
      if (bin >= sdk.size()) sdk.resize(bin + 1), arr.resize(bin + 1);
      sdk[bin].push_back(s.sdk_ms);
      arr[bin].push_back(s.arrival_ms);
    }
    for (size_t i = 0; i < sdk.size(); ++i) {
      if (sdk[i].empty()) continue;
      IsolationBin b;
      b.t = t0 + i * o.bin_s;
      b.samples = sdk[i].size();
      SetP50P99(sdk[i], &b.latency_ms_p50, &b.latency_ms_p99);
      SetP50P99(arr[i], &b.arrival_latency_ms_p50, &b.arrival_latency_ms_p99);
      result.bins.push_back(b);
    }
  }
  return result;
}

}  // namespace edgephys::loadgen
