#include "loadgen/relay_compare.h"

#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <thread>
#include <unordered_map>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "loadgen/emulation/emulation_plugins.h"
#include "loadgen/loopback_room.h"
#include "loadgen/paper_figures.h"
#include "loadgen/stats.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"
#include "relay/relay.h"

namespace edgephys::loadgen {
namespace {

constexpr size_t kHistory = 32;
constexpr uint32_t kFlagInteractable = 1u << 2, kFlagAvatar = 1u << 3, kFlagHand = 1u << 4;

double PosError(const EntityState& a, const EntityState& b) {
  double dx = a.position.x - b.position.x, dy = a.position.y - b.position.y,
         dz = a.position.z - b.position.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// Angle of the relative rotation conj(a) * b, robust near zero (atan2, not acos).
double RotErrorDeg(const EntityState& a, const EntityState& b) {
  const double ax = a.rotation.x, ay = a.rotation.y, az = a.rotation.z, aw = a.rotation.w;
  const double bx = b.rotation.x, by = b.rotation.y, bz = b.rotation.z, bw = b.rotation.w;
  double w = aw * bw + ax * bx + ay * by + az * bz;
  double x = aw * bx - ax * bw - ay * bz + az * by;
  double y = aw * by + ax * bz - ay * bw - az * bx;
  double z = aw * bz - ax * by + ay * bx - az * bw;
  double v = std::sqrt(x * x + y * y + z * z);
  return 2.0 * std::atan2(v, std::fabs(w)) * 180.0 / 3.14159265358979;
}

// What the host published, per entity: the last kHistory poses.
struct Truth {
  std::unordered_map<uint32_t, size_t> index;
  std::vector<std::array<EntityState, kHistory>> ring;
  std::vector<size_t> count;
  void Record(size_t i, const EntityState& s) { ring[i][count[i]++ % kHistory] = s; }
};

class Receiver : public ClientListener {
 public:
  explicit Receiver(const Truth* truth) : truth_(truth) {}
  void OnEntityUpdated(const RemoteEntity& e) override {
    if (!measuring) return;
    auto it = truth_->index.find(e.id);
    if (it == truth_->index.end()) return;
    size_t i = it->second;
    size_t n = std::min(truth_->count[i], kHistory);
    double best_pos = 1e9, best_rot = 0;
    for (size_t k = 0; k < n; ++k) {
      const EntityState& t = truth_->ring[i][k];
      double p = PosError(e.state, t);
      if (p < best_pos) {
        best_pos = p;
        best_rot = RotErrorDeg(e.state, t);
      }
    }
    if (n == 0) return;
    pos_errors.push_back(best_pos);
    rot_errors.push_back(best_rot);
    ++updates;
  }
  bool measuring = false;
  uint64_t updates = 0;
  std::vector<double> pos_errors, rot_errors;

 private:
  const Truth* truth_;
};

double Now(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

uint64_t UnixNow() {
  return static_cast<uint64_t>(std::chrono::duration_cast<std::chrono::seconds>(
                                   std::chrono::system_clock::now().time_since_epoch())
                                   .count());
}

RelayCompareResult RunOne(const RelayCompareOptions& o, ReplicationMode mode, uint32_t objects) {
  const std::string secret = Base64UrlEncode(std::vector<uint8_t>(8, 1)) + std::to_string(SecureRandom64());
  RelayConfig config;
  config.secret = secret;
  config.room_defaults.capacity = o.receivers + 4;
  config.room_defaults.tick_rate_hz = 60;
  config.room_defaults.max_entities_per_player = objects + 16;
  config.room_defaults.budgets = RoomBudgets::Unlimited();
  ReplicationConfig& r = config.room_defaults.replication;
  UseReplicationMode(mode, &r);
  r.fixed_rate_hz = o.rate_hz;
  r.position_step_m = o.position_step_m;
  r.rotation_bound_deg = o.rotation_bound_deg;
  r.position_threshold_m = o.position_threshold_m;
  r.rotation_threshold_deg = o.rotation_threshold_deg;
  r.shared_encoding = o.shared_encoding;

  auto loopback = asio::ip::make_address("127.0.0.1");
  const auto start = std::chrono::steady_clock::now();
  // In-process: the relay driven on this thread. External: only its address, its secret and
  // its /metrics (a room of its own per run, so runs against one relay do not meet).
  std::unique_ptr<UdpSocket> relay_socket;
  RelayCounters counters;
  std::unique_ptr<Relay> relay_owned;
  std::unique_ptr<RelayTarget> external;
  Endpoint relay_endpoint;
  std::string room = "compare";
  std::string token_secret = secret;
  if (o.external.enabled()) {
    external = std::make_unique<RelayTarget>(o.external, start);
    relay_endpoint = external->endpoint();
    room = "compare-" + std::to_string(SecureRandom64() % 1000000000);
    token_secret = o.external.secret;
  } else {
    relay_socket = std::move(*UdpSocket::Open(Endpoint(loopback, 0)));
    relay_owned = std::make_unique<Relay>(config, relay_socket.get(), &counters);
    relay_endpoint = relay_socket->LocalEndpoint();
  }

  auto token = [&](uint32_t player) { return MintJoinToken(token_secret, room, player); };
  Truth truth;
  std::vector<std::unique_ptr<UdpSocket>> sockets;
  std::vector<std::unique_ptr<Client>> clients;
  std::vector<std::unique_ptr<Receiver>> receivers;
  ClientConfig host_config;
  host_config.publish_rate_hz = 240;  // the host's own pacing is --rate; the SDK adds no delay
  ClientConfig receiver_config;
  receiver_config.state_decoder = EmulationStateDecoder();  // formats 1, 3, 4
  // Measurement bots: also against a relay run with --packet-auth false.
  receiver_config.require_packet_auth = host_config.require_packet_auth = false;
  for (uint32_t i = 0; i <= o.receivers; ++i) {
    sockets.push_back(std::move(*UdpSocket::Open(Endpoint(loopback, 0))));
    ClientListener* listener = nullptr;
    if (i > 0) {
      receivers.push_back(std::make_unique<Receiver>(&truth));
      listener = receivers.back().get();
    }
    clients.push_back(std::make_unique<Client>(i == 0 ? host_config : receiver_config,
                                               sockets.back().get(), listener));
    (void)clients.back()->Connect(ToRelayAddress(relay_endpoint), token(i + 1), Now(start));
  }
  auto step = [&] {
    double now = Now(start);
    if (relay_owned) relay_owned->Update(now, UnixNow());
    for (auto& c : clients) c->Update(now);
  };
  const bool ok = ConnectAndJoinAll(clients, room, 5.0, [&] { return Now(start); }, step);
  RelayCompareResult result;
  result.mode = mode;
  result.objects = objects;
  result.rate_hz = o.rate_hz;
  if (!ok) {
    std::fprintf(stderr, "relay-compare: clients failed to connect/join\n");
    for (auto& c : clients) c->Disconnect();
    return result;
  }

  Client& host = *clients[0];
  std::vector<uint32_t> ids;
  std::vector<Motion> motions;
  for (uint32_t i = 0; i < objects; ++i) {
    uint32_t role = i % 4;
    uint32_t flags = role == 0 ? kFlagAvatar : role == 3 ? kFlagInteractable : kFlagHand;
    motions.emplace_back(o.motion, i);
    EntityState s = motions.back().At(Now(start));
    auto id = host.Spawn({.position = s.position, .rotation = s.rotation, .flags = flags});
    if (!id.ok()) break;
    truth.index[*id] = ids.size();
    ids.push_back(*id);
  }
  truth.ring.resize(ids.size());
  truth.count.assign(ids.size(), 0);

  double next_publish = Now(start);
  double t0 = Now(start);
  double measure_start = t0 + o.warmup_s;
  double measure_end = measure_start + o.duration_s;
  bool measuring = false;
  std::vector<uint64_t> relay_bytes0(o.receivers), socket_bytes0(o.receivers),
      socket_packets0(o.receivers);
  RelayFigures figures0;        // external: /metrics at the window's start
  uint64_t host_bytes0 = 0;     // external: the host's socket at the window's start
  double last_progress = 0;
  for (;;) {
    double now = Now(start);
    if (now >= next_publish) {
      next_publish += 1.0 / o.rate_hz;
      for (size_t i = 0; i < ids.size(); ++i) {
        EntityState s = motions[i].At(now);
        s.entity_id = ids[i];
        truth.Record(i, s);
        (void)host.PublishTransform(ids[i], s.position, s.rotation);
      }
    }
    if (!measuring && now >= measure_start) {
      measuring = true;
      if (external) {
        figures0 = external->Read();
        host_bytes0 = host.stats()->bytes_received;
      }
      for (uint32_t k = 0; k < o.receivers; ++k) {
        const ConnectionStats* rs = relay_owned ? relay_owned->FindConnectionStats(k + 2) : nullptr;
        relay_bytes0[k] = rs ? rs->bytes_sent : 0;
        socket_bytes0[k] = clients[k + 1]->stats()->bytes_received;
        socket_packets0[k] = clients[k + 1]->stats()->packets_received;
        receivers[k]->measuring = true;
      }
    }
    if (now >= measure_end) break;
    step();
    if (o.progress && now - last_progress >= 0.5) {
      last_progress = now;
      std::fprintf(stderr, "\r  %-8s %4u objects  %5.1f / %.1f s ", std::string(ReplicationModeName(mode)).c_str(),
                   objects, std::max(0.0, now - measure_start), o.duration_s);
    }
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
  if (o.progress) std::fprintf(stderr, "\r%60s\r", "");

  double relay_total = 0, socket_total = 0, socket_packets = 0, updates = 0;
  std::vector<double> pos, rot;
  if (external) {
    // The relay's whole egress over the window, less what went to the host: the receivers'.
    const RelayFigures figures1 = external->Read();
    relay_total = figures0.ok && figures1.ok
                      ? figures1.bytes_sent - figures0.bytes_sent -
                            static_cast<double>(host.stats()->bytes_received - host_bytes0)
                      : kUnknown;
    for (auto& c : clients) c->Disconnect();
  }
  for (uint32_t k = 0; k < o.receivers; ++k) {
    const ConnectionStats* rs = relay_owned ? relay_owned->FindConnectionStats(k + 2) : nullptr;
    relay_total += rs ? static_cast<double>(rs->bytes_sent - relay_bytes0[k]) : 0;
    socket_total += static_cast<double>(clients[k + 1]->stats()->bytes_received - socket_bytes0[k]);
    socket_packets +=
        static_cast<double>(clients[k + 1]->stats()->packets_received - socket_packets0[k]);
    updates += static_cast<double>(receivers[k]->updates);
    pos.insert(pos.end(), receivers[k]->pos_errors.begin(), receivers[k]->pos_errors.end());
    rot.insert(rot.end(), receivers[k]->rot_errors.begin(), receivers[k]->rot_errors.end());
  }
  const double n = o.receivers * o.duration_s;
  result.egress_bytes_per_s_per_receiver = relay_total / n;
  result.socket_bytes_per_s_per_receiver = socket_total / n;
  result.ip_udp_bytes_per_s_per_receiver = socket_packets * kIpUdpHeaderBytes / n;
  result.updates_per_s_per_receiver = updates / n;
  result.bytes_per_update = updates > 0 ? relay_total / updates : 0;
  result.pos_err_max_m = Max(pos);
  result.pos_err_p99_m = Percentile(pos, 99);
  result.rot_err_max_deg = Max(rot);
  result.rot_err_p99_deg = Percentile(rot, 99);
  result.samples = pos.size();
  result.paper_bytes_per_s = mode == ReplicationMode::kPhoton ? PaperPhotonBytesPerS(objects)
                                                              : PaperRelayBytesPerS(objects);
  return result;
}

}  // namespace

std::vector<RelayCompareResult> RunRelayCompare(const RelayCompareOptions& options) {
  std::vector<RelayCompareResult> results;
  for (uint32_t objects : options.objects) {
    for (ReplicationMode mode : options.modes) results.push_back(RunOne(options, mode, objects));
  }
  return results;
}

}  // namespace edgephys::loadgen
