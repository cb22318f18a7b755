#include "loadgen/loopback_room.h"

#include <cmath>
#include <thread>

#include "client/client_endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"

namespace edgephys::loadgen {
namespace {

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

}  // namespace

LoopbackRoom::LoopbackRoom(const RelayConfig& config_in, std::string room, uint32_t clients,
                           const ClientConfig& host_config,
                           const std::vector<ClientListener*>& listeners)
    : room_(std::move(room)), start_(std::chrono::steady_clock::now()) {
  RelayConfig config = config_in;
  secret_ = Base64UrlEncode(std::vector<uint8_t>(8, 7)) + std::to_string(SecureRandom64());
  config.secret = secret_;
  auto loopback = asio::ip::make_address("127.0.0.1");
  relay_socket_ = std::move(*UdpSocket::Open(Endpoint(loopback, 0)));
  relay_ = std::make_unique<Relay>(config, relay_socket_.get(), &counters_);
  for (uint32_t i = 0; i < clients; ++i) {
    sockets_.push_back(std::move(*UdpSocket::Open(Endpoint(loopback, 0))));
    ClientListener* listener = i < listeners.size() ? listeners[i] : nullptr;
    clients_.push_back(std::make_unique<Client>(i == 0 ? host_config : ClientConfig{},
                                                sockets_.back().get(), listener));
  }
}

LoopbackRoom::~LoopbackRoom() {
  clients_.clear();
  relay_.reset();
}

bool LoopbackRoom::ConnectAndJoin(double timeout_s) {
  for (size_t i = 0; i < clients_.size(); ++i) {
    JoinToken t;
    t.room = room_;
    t.player_id = static_cast<uint32_t>(i + 1);
    t.expiry_unix_s = UnixNow() + 3600;
    t.nonce = SecureRandom64();
    (void)clients_[i]->Connect(ToRelayAddress(relay_socket_->LocalEndpoint()), *SignJoinToken(t, secret_), Now());
  }
  return ConnectAndJoinAll(clients_, room_, timeout_s, [this] { return Now(); },
                           [this] { Step(); });
}

bool ConnectAndJoinAll(const std::vector<std::unique_ptr<Client>>& clients, const std::string& room,
                       double timeout_s, const std::function<double()>& now,
                       const std::function<void()>& step) {
  auto run_until = [&](auto&& done) {
    const double end = now() + timeout_s;
    while (now() < end && !done()) {
      step();
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    }
    return done();
  };
  bool ok = run_until([&] {
    for (auto& c : clients) if (c->state() != ClientState::kConnected) return false;
    return true;
  });
  if (!ok) return false;
  for (auto& c : clients) (void)c->JoinRoom(room);
  return run_until([&] {
    for (auto& c : clients) if (!c->joined()) return false;
    return true;
  });
}

void LoopbackRoom::UpdateRelay() { relay_->Update(Now(), UnixNow()); }

void LoopbackRoom::UpdateClients() {
  const double now = Now();
  for (auto& c : clients_) c->Update(now);
}


uint64_t HistogramCount(const AtomicHistogram<10>& h) {
  uint64_t n = 0;
  for (size_t i = 0; i <= 10; ++i) n += h.bucket(i);
  return n;
}

double Dist(const Vec3f& a, const Vec3f& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

RelayConfig BenchmarkRelayConfig(uint32_t receivers, uint32_t max_entities, float position_step_m,
                                 float rotation_bound_deg) {
  RelayConfig config;
  config.room_defaults.capacity = receivers + 2;
  config.room_defaults.tick_rate_hz = 60;
  config.room_defaults.max_entities_per_player = max_entities;
  config.room_defaults.budgets = RoomBudgets::Unlimited();
  config.room_defaults.replication.position_step_m = position_step_m;
  config.room_defaults.replication.rotation_bound_deg = rotation_bound_deg;
  config.limits.spawns_per_s = 0;
  config.limits.packets_per_s = 0;
  config.limits.bytes_per_s = 0;
  return config;
}

SpawnDesc OffloadedSpawn(const EntitySpec& s) {
  SpawnDesc d{.position = s.position, .rotation = s.rotation, .scale = s.scale,
              .flags = s.flags | static_cast<uint32_t>(schema::EntityFlags::Offloaded),
              .name = s.name};
  d.rigid_body = s.rigid_body;
  d.colliders = s.colliders;
  d.soft_body = s.soft_body;
  return d;
}

void WindowMeter::Start(LoopbackRoom& world, size_t receivers) {
  receivers_ = receivers;
  relay_bytes0_.assign(receivers, 0);
  socket_bytes0_.assign(receivers, 0);
  socket_packets0_.assign(receivers, 0);
  for (size_t k = 0; k < receivers; ++k) {
    const ConnectionStats* rs = world.relay().FindConnectionStats(static_cast<uint32_t>(k + 2));
    relay_bytes0_[k] = rs ? rs->bytes_sent : 0;
    socket_bytes0_[k] = world.client(k + 1).stats()->bytes_received;
    socket_packets0_[k] = world.client(k + 1).stats()->packets_received;
  }
  RelayCounters& c = world.counters();
  steps0_ = RelayCounters::Get(c.physics_steps);
  step_sum0_ = c.physics_step_seconds.sum();
  step_count0_ = HistogramCount(c.physics_step_seconds);
  t0_ = world.Now();
}

WindowMeter::Totals WindowMeter::Finish(LoopbackRoom& world) const {
  Totals t;
  t.elapsed_s = world.Now() - t0_;
  for (size_t k = 0; k < receivers_; ++k) {
    const ConnectionStats* rs = world.relay().FindConnectionStats(static_cast<uint32_t>(k + 2));
    t.relay_bytes += rs ? static_cast<double>(rs->bytes_sent - relay_bytes0_[k]) : 0;
    t.socket_bytes += static_cast<double>(world.client(k + 1).stats()->bytes_received - socket_bytes0_[k]);
    t.socket_packets +=
        static_cast<double>(world.client(k + 1).stats()->packets_received - socket_packets0_[k]);
  }
  RelayCounters& c = world.counters();
  t.physics_steps = RelayCounters::Get(c.physics_steps) - steps0_;
  const uint64_t observed = HistogramCount(c.physics_step_seconds) - step_count0_;
  t.step_ms_mean = observed > 0 ? (c.physics_step_seconds.sum() - step_sum0_) / static_cast<double>(observed) * 1000 : 0;
  return t;
}

}  // namespace edgephys::loadgen
