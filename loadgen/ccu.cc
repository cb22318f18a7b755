#include "loadgen/ccu.h"

#include <pthread.h>
#include <time.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <thread>
#include <unordered_map>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "client/snapshot_buffer.h"
#include "loadgen/motion.h"
#include "loadgen/pose_history.h"
#include "loadgen/stats.h"
#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/network_simulator.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"
#include "loadgen/relay_target.h"

namespace edgephys::loadgen {
namespace {

using Clock = std::chrono::steady_clock;
constexpr uint32_t kFlag(schema::EntityFlags f) { return static_cast<uint32_t>(f); }
constexpr uint8_t kGrabbed = static_cast<uint8_t>(schema::PhysicsEventKind::Grabbed);
constexpr uint8_t kReleased = static_cast<uint8_t>(schema::PhysicsEventKind::Released);
constexpr uint8_t kTriggerEnter = static_cast<uint8_t>(schema::PhysicsEventKind::TriggerEnter);
constexpr uint32_t kInterpolationSampleEvery = 10;  // bots keeping jitter buffers

// CLOCK_REALTIME in seconds: the clock of the kernel's receive timestamps
// (RemoteEntity::arrival_unix_s), so publish times taken with it need no conversion.
double RealtimeNow() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<double>(ts.tv_sec) + ts.tv_nsec * 1e-9;
}

struct EventRecord {
  uint32_t room;
  uint8_t kind;
  uint32_t entity;
  double t;
};

class World;

class Bot : public ClientListener {
 public:
  Bot(World* world, uint32_t index, uint32_t room) : world_(world), index_(index), room_(room) {}
  void OnEntitySpawned(const RemoteEntity& e) override { ++spawns_seen[e.id]; }
  void OnEntityUpdated(const RemoteEntity& e) override;
  void OnPhysicsEvent(uint8_t kind, uint32_t a, uint32_t b) override;

  void Tick(double now);

  World* world_;
  uint32_t index_;
  uint32_t room_;
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<ImpairedSocket> link;  // --impaired: the client's socket, over `socket`
  std::unique_ptr<Client> client;
  double start_at = 0;
  double joined_at = -1;
  bool join_requested = false;
  bool spawned = false;
  uint32_t head = 0, left = 0, right = 0, box = 0;
  Vec3f home;
  double next_publish = 0;
  Vec3f last_right{};  // the right hand's previous published pose
  bool published_right = false;
  // Right-hand publishes for latency matching: t = the bot pass's start (World::Now()), as
  // the SDK latency counts it; unix_s = CLOCK_REALTIME at the PublishTransform() call.
  PoseHistory right_history;
  // Grab cycle.
  int phase = 0;  // 0 free, 1 reaching, 2 requested, 3 holding
  double phase_at = 0;
  double next_grab = 0;
  double grab_requested_at = -1;
  double grab_requested_unix_s = 0;  // CLOCK_REALTIME at the Grab() call
  bool hovering = false;
  std::unordered_map<uint32_t, int> spawns_seen;
  std::map<std::pair<uint8_t, uint32_t>, int> events_seen;  // (kind, entity) -> count
  std::unordered_map<uint32_t, SnapshotBuffer> buffers;      // watched hands
  std::unordered_map<uint32_t, Vec3f> last_seen;
};

class World {
 public:
  const CcuOptions& o;
  RelayTarget* relay = nullptr;
  std::vector<std::unique_ptr<Bot>> bots;
  // RoomEntityKey(room, id) -> bot: rooms reuse entity ids (one block per slot), so the id
  // alone names one entity in every room.
  std::unordered_map<uint64_t, Bot*> right_hand_owner;
  std::unordered_map<uint64_t, Bot*> box_owner;
  std::vector<EventRecord> events;  // grab/release as the grabbing bot saw them
  std::vector<double> latencies_ms, grab_latencies_ms;
  // The same, ending at the kernel's arrival time at the receiver's socket.
  std::vector<double> arrival_latencies_ms, grab_arrival_latencies_ms;
  uint64_t hand_updates = 0;
  // Deliveries owed while measuring: for each right-hand publish that moved the hand by at
  // least the 1 mm lattice step (a pose selective sync must forward), one per measuring bot
  // in the publisher's room (itself excluded).
  double hand_updates_owed = 0;
  std::vector<uint32_t> measuring_in_room;  // per room index
  uint64_t hand_unmatched = 0, cross_room_samples = 0;
  FILE* samples = nullptr;  // --samples CSV, or null
  bool measuring = false;
  Clock::time_point start;
  explicit World(const CcuOptions& options) : o(options) {}
  double Now() const { return std::chrono::duration<double>(Clock::now() - start).count(); }
};

// Whether bot `index` is one of the --impaired fraction: every 1/f-th bot, so they spread over
// the rooms (bots go round the rooms in index order).
bool Impaired(const CcuOptions& o, uint32_t index) {
  return o.impaired_fraction > 0 &&
         std::floor((index + 1) * o.impaired_fraction) > std::floor(index * o.impaired_fraction);
}

Vec3f HandPath(const Bot& b, double t, float side) {
  return AvatarHandPosition(b.home, b.index_, t, side);
}

void Bot::OnEntityUpdated(const RemoteEntity& e) {
  auto it = world_->right_hand_owner.find(RoomEntityKey(room_, e.id));
  if (it == world_->right_hand_owner.end() || it->second == this) return;
  if (index_ % world_->o.measure_every != 0) return;  // not a measuring bot
  const Bot& sender = *it->second;
  double now = world_->Now();
  if (index_ % kInterpolationSampleEvery == 0) {
    // The playout delay a jitter buffer would pick is estimated by a sample of the bots (each
    // keeps a buffer per watched hand); all bots would cost the bot thread a fifth of its CPU.
    SnapshotBuffer& buffer = buffers[e.id];
    buffer.Insert({.sender_time_s = e.state_time_ms / 1000.0, .position = e.state.position,
                   .rotation = e.state.rotation},
                  now);
  }
  Vec3f& last = last_seen[e.id];
  const bool repeat = last.x == e.state.position.x && last.y == e.state.position.y &&
                      last.z == e.state.position.z;
  last = e.state.position;
  if (!world_->measuring || repeat) return;  // a resend of a pose already seen
  ++world_->hand_updates;
  if (const PoseHistory::Publish* sent = sender.right_history.Match(e.state.position)) {
    const double sdk_ms = (now - sent->t) * 1000.0;
    const double arrival_ms = (e.arrival_unix_s - sent->unix_s) * 1000.0;
    world_->latencies_ms.push_back(sdk_ms);
    world_->arrival_latencies_ms.push_back(arrival_ms);
    world_->cross_room_samples += sender.room_ != room_;
    if (world_->samples != nullptr) {
      std::fprintf(world_->samples, "hand,%.4f,%u,%u,%u,%u,%u,%.3f,%.3f\n", now, room_, index_,
                   e.id, sender.room_, sender.index_, sdk_ms, arrival_ms);
    }
    return;
  }
  ++world_->hand_unmatched;
  if (world_->samples != nullptr) {
    std::fprintf(world_->samples, "hand_unmatched,%.4f,%u,%u,%u,%u,%u,,\n", now, room_, index_, e.id,
                 sender.room_, sender.index_);
  }
}

void Bot::OnPhysicsEvent(uint8_t kind, uint32_t a, uint32_t b) {
  if (kind == kTriggerEnter && a == right && b == box) hovering = true;
  if (kind != kGrabbed && kind != kReleased) return;
  ++events_seen[{kind, a}];
  double now = world_->Now();
  auto owner = world_->box_owner.find(RoomEntityKey(room_, a));
  if (owner == world_->box_owner.end()) return;
  Bot* grabber = owner->second;
  if (grabber == this) {
    world_->events.push_back({room_, kind, a, now});
    if (kind == kGrabbed) phase = 3, phase_at = now;
  } else if (kind == kGrabbed && grabber->grab_requested_at > 0 && world_->measuring &&
             index_ % world_->o.measure_every == 0) {
    const double sdk_ms = (now - grabber->grab_requested_at) * 1000.0;
    const double arrival_ms = (client->packet_arrival_unix_s() - grabber->grab_requested_unix_s) * 1000.0;
    world_->grab_latencies_ms.push_back(sdk_ms);
    world_->grab_arrival_latencies_ms.push_back(arrival_ms);
    world_->cross_room_samples += grabber->room_ != room_;
    if (world_->samples != nullptr) {
      std::fprintf(world_->samples, "grab,%.4f,%u,%u,%u,%u,%u,%.3f,%.3f\n", now, room_, index_, a,
                   grabber->room_, grabber->index_, sdk_ms, arrival_ms);
    }
  }
}

void Bot::Tick(double now) {
  Client& c = *client;
  if (c.state() != ClientState::kConnected) return;
  if (!c.joined()) return;
  if (joined_at < 0) joined_at = now;
  if (!spawned) {
    spawned = true;
    const uint32_t offloaded = kFlag(schema::EntityFlags::Offloaded);
    if (index_ < world_->o.rooms) {  // the first bot of each room lays the floor
      SpawnDesc ground{.position = {0, -0.5f, 0}, .flags = offloaded};
      ground.colliders.push_back(BoxCollider({200, 0.5f, 200}));
      (void)c.Spawn(ground);
    }
    AvatarIds avatar;
    (void)SpawnAvatar(c, home, index_, now, &avatar);  // a refusal leaves that id 0 (unused)
    head = avatar.head;
    left = avatar.left;
    right = avatar.right;
    SpawnDesc b{.position = {home.x, 0.1f, home.z},
                .flags = offloaded | kFlag(schema::EntityFlags::Interactable)};
    b.rigid_body = RigidBodySpec{};
    b.colliders.push_back(BoxCollider({0.1f, 0.1f, 0.1f}));
    box = *c.Spawn(b);
    world_->right_hand_owner[RoomEntityKey(room_, right)] = this;
    world_->box_owner[RoomEntityKey(room_, box)] = this;
    next_grab = now + 2.0 + (index_ % 50) * 0.1;
    return;
  }
  if (now < next_publish) return;
  next_publish = now + 1.0 / world_->o.publish_hz;
  (void)c.PublishTransform(head, {home.x, 1.6f + 0.05f * std::sin(float(now)), home.z}, {});
  (void)c.PublishTransform(left, HandPath(*this, now, -1.f), {});
  Vec3f r = HandPath(*this, now, 1.f);
  switch (phase) {
    case 0:
      if (now >= next_grab) phase = 1, phase_at = now, hovering = false;
      break;
    case 1: {  // reach down to the box
      const RemoteEntity* e = c.FindEntity(box);
      if (e != nullptr) r = {e->state.position.x, e->state.position.y + 0.05f, e->state.position.z};
      if (hovering) {
        grab_requested_unix_s = RealtimeNow();
        (void)c.Grab(box, right);
        grab_requested_at = now;
        phase = 2, phase_at = now;
      } else if (now - phase_at > 2.0) {
        phase = 0, next_grab = now + 3.0;  // the box rolled away; try later
      }
      break;
    }
    case 2:  // waiting for Grabbed
      if (const RemoteEntity* e = c.FindEntity(box)) r = {e->state.position.x, e->state.position.y + 0.05f, e->state.position.z};
      if (now - phase_at > 2.0) phase = 0, next_grab = now + 3.0;
      break;
    case 3:  // carrying
      if (now - phase_at > 2.0) {
        (void)c.Release(box);
        phase = 0;
        next_grab = now + 4.0;
      }
      break;
  }
  const double published_unix_s = RealtimeNow();
  const float mx = r.x - last_right.x, my = r.y - last_right.y, mz = r.z - last_right.z;
  if (world_->measuring && published_right && mx * mx + my * my + mz * mz >= 1e-6f) {
    const bool self_measuring = index_ % world_->o.measure_every == 0;
    world_->hand_updates_owed += world_->measuring_in_room[room_] - (self_measuring ? 1 : 0);
  }
  last_right = r;
  published_right = true;
  (void)c.PublishTransform(right, r, {});
  right_history.Add({.t = now, .unix_s = published_unix_s, .position = r});
}

CcuResult RunOne(const CcuOptions& o, uint32_t users) {
  World world(o);
  world.start = Clock::now();
  RelayConfig config;
  config.secret = "ccu-" + std::to_string(SecureRandom64());
  config.max_clients = users + 64;
  config.room_defaults.capacity = users / std::max(1u, o.rooms) + 16;
  config.room_defaults.tick_rate_hz = o.tick_rate_hz;
  config.room_defaults.replication.shared_encoding = o.shared_encoding;
  config.packet_auth = o.packet_auth;
  config.limits.max_sessions_per_address = users + 64;  // every bot comes from 127.0.0.1
  config.limits.handshakes_per_s = 100000;
  config.connection.timeout_s = 10;
  config.physics_threads = std::max<size_t>(1, o.relay_threads);
  std::unique_ptr<RelayTarget> target =
      o.external.enabled() ? std::make_unique<RelayTarget>(o.external, world.start)
                           : std::make_unique<RelayTarget>(config, world.start);
  RelayTarget& relay = *target;
  world.relay = &relay;
  std::unique_ptr<FILE, int (*)(FILE*)> samples(nullptr, &std::fclose);
  if (!o.samples_path.empty()) {
    const std::string path = o.users.size() > 1 ? o.samples_path + "." + std::to_string(users)
                                                : o.samples_path;
    samples.reset(std::fopen(path.c_str(), "w"));
    if (!samples) std::fprintf(stderr, "ccu: cannot write --samples %s\n", path.c_str());
    else std::fprintf(samples.get(), "kind,t_s,room,bot,entity,sender_room,sender,sdk_ms,arrival_ms\n");
    world.samples = samples.get();
  }

  world.measuring_in_room.assign(std::max(1u, o.rooms), 0);
  for (uint32_t i = 0; i < users; ++i) {
    if (i % o.measure_every == 0) ++world.measuring_in_room[i % std::max(1u, o.rooms)];
  }
  for (uint32_t i = 0; i < users; ++i) {
    auto bot = std::make_unique<Bot>(&world, i, i % std::max(1u, o.rooms));
    uint32_t slot = i / std::max(1u, o.rooms);
    bot->home = {static_cast<float>((slot % 32) * 2.0), 0, static_cast<float>((slot / 32) * 2.0)};
    bot->start_at = o.ramp_s * i / std::max(1u, users);
    world.bots.push_back(std::move(bot));
  }
  auto token = [&](const Bot& b) { return relay.Token("ccu-" + std::to_string(b.room_), b.index_ + 1); };
  ClientConfig cc;
  cc.publish_rate_hz = 240;  // the bot paces itself; the SDK adds no batching delay
  cc.require_packet_auth = false;  // bots: also --packet-auth false
  cc.handshake_timeout_s = 10;
  cc.record_arrival_times = true;  // kernel receive timestamps: the arrival latencies

  CcuResult result;
  result.users = users;
  result.rooms = o.rooms;
  const double end = o.ramp_s + o.duration_s;
  double next_sample = 1.0;
  // Server-side figures: the in-process relay's counters or the external relay's /metrics.
  RelayFigures last = relay.Read();
  last.t = 0;
  if (!last.ok) ++result.metrics_failures, result.metrics_error = last.error;
  std::vector<double> step_ms;
  std::vector<double> loop_ms;  // one pass over all bots (the load generator's own delay)
  for (;;) {
    double now = world.Now();
    if (now >= end) break;
    world.measuring = now >= o.ramp_s;
    for (auto& b : world.bots) {
      if (!b->client) {
        if (now < b->start_at) continue;
        b->socket = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
        DatagramSocket* socket = b->socket.get();
        if (Impaired(o, b->index_)) {
          NetworkConditions link{.loss = o.impaired_loss, .latency_s = o.impaired_delay_ms / 1000};
          NetworkConditions up = link, down = link;
          up.seed = o.seed * 1000003 + 2 * b->index_;
          down.seed = up.seed + 1;
          b->link = std::make_unique<ImpairedSocket>(socket, up, down);
          b->link->Update(now);
          socket = b->link.get();
        }
        b->client = std::make_unique<Client>(cc, socket, b.get());
        (void)b->client->Connect(ToRelayAddress(relay.endpoint()), token(*b), now);
      }
      // Publish first, then Update: the client sends what was just published in this pass
      // (Update receives, then sends), instead of one whole pass over the bots later.
      b->Tick(now);
      if (b->link) b->link->Update(now);
      b->client->Update(now);
      if (b->client->state() == ClientState::kConnected && !b->join_requested) {
        (void)b->client->JoinRoom("ccu-" + std::to_string(b->room_));
        b->join_requested = true;
      }
    }
    if (world.measuring) loop_ms.push_back((world.Now() - now) * 1000.0);
    if (now >= next_sample) {
      next_sample += 1.0;
      CcuSample s;
      s.t = now;
      for (auto& b : world.bots) s.users += b->client && b->client->joined();
      RelayFigures f = relay.Read();
      if (!f.ok) {
        ++result.metrics_failures, result.metrics_error = f.error;
        continue;  // this second has no server figures; the next one spans two
      }
      double dt = now - last.t;
      if (!last.ok) {  // no baseline yet
        last = f;
        last.t = now;
        continue;
      }
      s.egress_bytes_per_s = (f.bytes_sent - last.bytes_sent) / dt;
      s.ingress_bytes_per_s = (f.bytes_received - last.bytes_received) / dt;
      s.updates_per_s = (f.entity_updates_sent - last.entity_updates_sent) / dt;
      s.resends_per_s = (f.reliable_resends - last.reliable_resends) / dt;
      s.relay_cpu = (f.cpu_s - last.cpu_s) / dt;  // NaN when unknown
      const double steps = f.physics_steps - last.physics_steps;
      s.physics_step_ms = steps > 0 ? (f.physics_step_seconds_sum - last.physics_step_seconds_sum) / steps * 1000 : 0;
      if (world.measuring && s.physics_step_ms > 0) step_ms.push_back(s.physics_step_ms);
      last = f;
      last.t = now;
      result.series.push_back(s);
      if (o.progress) {
        std::fprintf(stderr, "\r  ccu %u users: t=%5.1f joined=%u egress=%.0f KB/s cpu=%.2f ", users, now,
                     s.users, s.egress_bytes_per_s / 1000, s.relay_cpu);
      }
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  if (o.progress) std::fprintf(stderr, "\n");

  // Reliable delivery: every other bot's spawns, and every grab/release seen by its grabber.
  for (auto& b : world.bots) result.connected += b->client && b->client->joined();
  for (auto& receiver : world.bots) {
    if (!receiver->client || !receiver->client->joined()) continue;
    for (auto& other : world.bots) {
      if (other.get() == receiver.get() || other->room_ != receiver->room_ || other->box == 0) continue;
      for (uint32_t id : {other->head, other->left, other->right, other->box}) {
        ++result.reliable_expected;
        auto it = receiver->spawns_seen.find(id);
        if (it == receiver->spawns_seen.end()) ++result.reliable_lost;
        else if (it->second > 1) result.reliable_duplicated += it->second - 1;
      }
    }
    for (const EventRecord& ev : world.events) {
      if (ev.room != receiver->room_ || receiver->joined_at < 0 || receiver->joined_at > ev.t - 1.0 ||
          ev.t > end - 1.0) {
        continue;  // joined after it, or too close to the end to have arrived
      }
      ++result.reliable_expected;
      auto it = receiver->events_seen.find({ev.kind, ev.entity});
      if (it == receiver->events_seen.end()) ++result.reliable_lost;
    }
  }
  SetP50P99(world.latencies_ms, &result.latency_ms_p50, &result.latency_ms_p99);
  SetP50P99(world.grab_latencies_ms, &result.grab_latency_ms_p50, &result.grab_latency_ms_p99);
  SetP50P99(world.arrival_latencies_ms, &result.arrival_latency_ms_p50,
            &result.arrival_latency_ms_p99);
  SetP50P99(world.grab_arrival_latencies_ms, &result.grab_arrival_latency_ms_p50,
            &result.grab_arrival_latency_ms_p99);
  for (auto& b : world.bots) {
    if (b->client) result.arrival_time_fallbacks += b->client->arrival_time_fallbacks();
    if (b->link) {
      ++result.impaired_users;
      result.impaired_dropped_up += b->link->up_stats().dropped;
      result.impaired_dropped_down += b->link->down_stats().dropped;
    }
  }
  result.relay_wait_ms_mean = 500.0 / o.tick_rate_hz;
  result.physics_step_ms_p99 = Percentile(step_ms, 99);
  SetP50P99(loop_ms, &result.bot_pass_ms_p50, &result.bot_pass_ms_p99);
  std::vector<double> delays;
  for (auto& b : world.bots) {
    for (auto& [id, buf] : b->buffers) delays.push_back(buf.target_delay_s() * 1000);
  }
  result.interpolation_delay_ms = Median(delays);
  double cpu_sum = 0, egress_sum = 0, updates_sum = 0;
  int n = 0;
  for (const CcuSample& s : result.series) {
    if (s.t < o.ramp_s) continue;
    cpu_sum += s.relay_cpu;
    egress_sum += s.egress_bytes_per_s;
    updates_sum += s.updates_per_s;
    ++n;
  }
  result.relay_cpu_mean = n ? cpu_sum / n : 0;
  result.egress_bytes_per_s_per_user = n && users ? egress_sum / n / users : 0;
  result.relay_us_per_update = updates_sum > 0 ? cpu_sum / updates_sum * 1e6 : 0;
  result.bytes_per_update = updates_sum > 0 ? egress_sum / updates_sum : 0;
  // Each measuring bot watches every other bot's right hand in its room; owed are the poses
  // the publishers actually sent (their loop may publish below publish_hz) that moved the hand
  // by at least the lattice step (a hand resting over a box is rightly not resent).
  result.expected_update_ratio =
      world.hand_updates_owed > 0 ? world.hand_updates / world.hand_updates_owed : 0;
  result.hand_updates_measured = world.hand_updates;
  result.hand_unmatched = world.hand_unmatched;
  result.cross_room_samples = world.cross_room_samples;
  // Leave the relay clean (an external one keeps serving: no traffic to bots that are gone).
  for (auto& b : world.bots) {
    if (b->client) b->client->Disconnect();
  }
  return result;
}

}  // namespace

std::vector<CcuResult> RunCcu(const CcuOptions& options) {
  std::vector<CcuResult> results;
  for (uint32_t users : options.users) results.push_back(RunOne(options, users));
  return results;
}

}  // namespace edgephys::loadgen
