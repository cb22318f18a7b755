#include "loadgen/hostile.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <memory>
#include <mutex>
#include <thread>
#include <unordered_map>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "loadgen/hostile_attacks.h"
#include "loadgen/stats.h"
#include "metrics/metrics_exporter.h"
#include "relay/relay_metrics.h"

namespace edgephys::loadgen {
namespace {

using Clock = std::chrono::steady_clock;

// A pose's sequence number, modulo kRing, as a point of a 64 x 64 lattice of 2 cm.
constexpr uint32_t kRing = 4096;
constexpr float kLattice = 0.02f;
Vec3f PoseOf(uint32_t seq, uint32_t index) {
  const uint32_t k = seq % kRing;
  return {static_cast<float>(k % 64) * kLattice, 1.0f + 0.05f * static_cast<float>(index),
          static_cast<float>(k / 64) * kLattice};
}
uint32_t SeqOf(const Vec3f& p) {
  const long x = std::lround(p.x / kLattice), z = std::lround(p.z / kLattice);
  return static_cast<uint32_t>(std::clamp(x, 0L, 63L) + 64 * std::clamp(z, 0L, 63L));
}

class HonestRoom;

// One honest member: publishes its entity's pose, counts everyone else's.
class Member final : public ClientListener {
 public:
  Member(HonestRoom* room, uint32_t i) : room_(room), index(i) {}
  void OnEntityUpdated(const RemoteEntity& e) override;

  struct Track {
    uint32_t last = UINT32_MAX;  // last sequence (mod kRing) seen
    double last_t = -1;          // when, in the phase; -1: none yet
    uint64_t count = 0;
    double max_gap = 0;
  };
  HonestRoom* room_;
  uint32_t index;
  std::unique_ptr<RecordingSocket> socket;
  std::unique_ptr<Client> client;
  bool join_sent = false;
  uint32_t entity = 0;
  uint32_t seq = 0;
  double next_publish = 0;
  std::array<double, kRing> sent_at{};
  std::unordered_map<uint32_t, Track> tracks;  // by sender entity
};

// The honest members of one room on their own thread, and (room A) the late-joining probe.
class HonestRoom {
 public:
  HonestRoom(const HostileOptions& o, RelayTarget* relay, Clock::time_point t0, std::string room,
             asio::ip::address address, uint32_t first_player)
      : o_(o), relay_(relay), t0_(t0), room_(std::move(room)), address_(address),
        first_player_(first_player) {}
  ~HonestRoom() { Stop(); }

  double Now() const { return std::chrono::duration<double>(Clock::now() - t0_).count(); }

  std::string Start() {
    ClientConfig cc;
    cc.publish_rate_hz = 240;  // the member paces itself (--publish-hz); no SDK batching delay
    cc.require_packet_auth = false;  // a measurement tool, also against --packet-auth false
    cc_ = cc;
    for (uint32_t i = 0; i < o_.honest; ++i) {
      auto m = std::make_unique<Member>(this, i);
      auto socket = UdpSocket::Open(Endpoint(address_, 0));
      if (!socket.ok()) return "honest socket: " + socket.status().ToString();
      m->socket = std::make_unique<RecordingSocket>(std::move(*socket));
      m->client = std::make_unique<Client>(cc, m->socket.get(), m.get());
      (void)m->client->Connect(ToRelayAddress(relay_->endpoint()), relay_->Token(room_, first_player_ + i), Now());
      members_.push_back(std::move(m));
    }
    thread_ = std::thread([this] { Run(); });
    return "";
  }

  void Stop() {
    if (stop_.exchange(true)) return;
    if (thread_.joinable()) thread_.join();
    for (auto& m : members_) m->client->Disconnect();
    DropProbe();
  }

  // Every member joined, spawned and receiving every other member's updates.
  bool WaitReady(double timeout_s) {
    const double end = Now() + timeout_s;
    while (Now() < end) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        bool ready = true;
        for (auto& m : members_) {
          ready = ready && m->entity != 0 && m->tracks.size() + 1 >= members_.size();
        }
        if (ready) return true;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return false;
  }

  RecordingSocket* victim() { return members_.empty() ? nullptr : members_[0]->socket.get(); }

  void BeginPhase(double now) {
    std::lock_guard<std::mutex> lock(mu_);
    measuring_ = true;
    phase_start_ = now;
    latencies_.clear();
    for (auto& m : members_) {
      for (auto& [id, t] : m->tracks) t = {t.last, -1, 0, 0};
    }
    probe_ = {};
    probe_requested_ = probe_done_ = false;
    DropProbe();  // one still joining from the last phase
  }
  void StartProbe() {
    std::lock_guard<std::mutex> lock(mu_);
    probe_requested_ = true;
  }
  bool ProbeFinished() {
    std::lock_guard<std::mutex> lock(mu_);
    return probe_requested_ && probe_done_;
  }
  bool ProbeStarted() {
    std::lock_guard<std::mutex> lock(mu_);
    return probe_requested_;
  }

  HonestRoomFigures EndPhase(double now, ProbeFigures* probe) {
    std::lock_guard<std::mutex> lock(mu_);
    measuring_ = false;
    HonestRoomFigures f;
    const double seconds = std::max(1e-9, now - phase_start_);
    f.members = static_cast<uint32_t>(members_.size());
    std::vector<double> rates;
    for (auto& receiver : members_) {
      f.connected += receiver->client->state() == ClientState::kConnected && receiver->client->joined();
      for (auto& sender : members_) {
        if (sender == receiver) continue;
        Member::Track t;
        if (auto it = receiver->tracks.find(sender->entity); it != receiver->tracks.end()) t = it->second;
        f.updates += t.count;
        rates.push_back(static_cast<double>(t.count) / seconds);
        const double tail = now - (t.last_t >= 0 ? t.last_t : phase_start_);
        f.max_gap_s = std::max({f.max_gap_s, t.max_gap, tail});
      }
    }
    double sum = 0;
    for (double r : rates) sum += r;
    f.rate = rates.empty() ? 0 : sum / static_cast<double>(rates.size());
    f.min_pair_rate = rates.empty() ? 0 : *std::min_element(rates.begin(), rates.end());
    SetP50P99(latencies_, &f.latency_ms_p50, &f.latency_ms_p99);
    if (probe != nullptr) {
      *probe = probe_;
      if (probe_requested_ && !probe_done_) probe->failure = "not complete at the phase's end";
    }
    probe_requested_ = false;
    return f;
  }

  // Member callback (honest thread, under mu_).
  void Received(Member& receiver, const RemoteEntity& e) {
    auto it = owners_.find(e.id);
    if (it == owners_.end()) return;
    const Member& sender = *it->second;
    const uint32_t k = SeqOf(e.state.position);
    Member::Track& t = receiver.tracks[e.id];
    if (k == t.last) return;  // a resend of the same pose
    t.last = k;
    if (!measuring_) return;
    const double now = Now();
    ++t.count;
    t.max_gap = std::max(t.max_gap, now - (t.last_t >= 0 ? t.last_t : phase_start_));
    t.last_t = now;
    latencies_.push_back((now - sender.sent_at[k]) * 1000.0);
  }

 private:
  void Run() {
    while (!stop_.load()) {
      {
        std::lock_guard<std::mutex> lock(mu_);
        const double now = Now();
        for (auto& m : members_) Tick(*m, now);
        TickProbe(now);
      }
      std::this_thread::sleep_for(std::chrono::microseconds(300));
    }
  }

  void Tick(Member& m, double now) {
    Client& c = *m.client;
    if (m.entity != 0 && now >= m.next_publish) {
      const double period = 1.0 / o_.publish_hz;
      m.next_publish = std::max(m.next_publish + period, now - period);
      ++m.seq;
      m.sent_at[m.seq % kRing] = now;
      (void)c.PublishTransform(m.entity, PoseOf(m.seq, m.index), {});
    }
    c.Update(now);
    if (c.state() == ClientState::kConnected && !m.join_sent) {
      (void)c.JoinRoom(room_);
      m.join_sent = true;
    }
    if (c.joined() && m.entity == 0) {
      // An avatar: the critical class (48 Hz by default), as a player's head or hand.
      auto id = c.Spawn({.position = PoseOf(0, m.index),
                         .flags = static_cast<uint32_t>(schema::EntityFlags::Avatar)});
      if (id.ok()) {
        m.entity = *id;
        owners_[*id] = &m;
        m.next_publish = now;
      }
    }
  }

  void DropProbe() {
    if (!probe_client_) return;
    probe_client_->Disconnect();
    probe_client_.reset();
    probe_socket_.reset();
  }

  // The late joiner: connects, joins, and waits for every entity a member holds.
  void TickProbe(double now) {
    if (probe_done_) DropProbe();
    if (!probe_requested_ || probe_done_) return;
    if (!probe_client_) {
      auto socket = UdpSocket::Open(Endpoint(address_, 0));
      if (!socket.ok()) {
        probe_.failure = "probe socket: " + socket.status().ToString();
        probe_done_ = true;
        return;
      }
      probe_socket_ = std::move(*socket);
      probe_client_ = std::make_unique<Client>(cc_, probe_socket_.get());
      probe_.started = true;
      probe_.target = static_cast<uint32_t>(members_[0]->client->entities().size() + 1);
      probe_started_at_ = now;
      probe_join_sent_ = false;
      (void)probe_client_->Connect(ToRelayAddress(relay_->endpoint()),
                                   relay_->Token(room_, first_player_ + 100 + probes_++), now);
    }
    Client& c = *probe_client_;
    c.Update(now);
    if (c.state() == ClientState::kConnected && !probe_join_sent_) {
      (void)c.JoinRoom(room_);
      probe_join_sent_ = true;
    }
    if (c.joined() && !probe_.joined) {
      probe_.joined = true;
      probe_.join_ms = (now - probe_started_at_) * 1000.0;
    }
    probe_.entities = static_cast<uint32_t>(c.entities().size());
    if (c.joined() && probe_.entities >= probe_.target) {
      probe_.complete = true;
      probe_.state_ms = (now - probe_started_at_) * 1000.0;
      probe_done_ = true;
    } else if (c.state() == ClientState::kRejected || c.state() == ClientState::kFailed ||
               c.state() == ClientState::kDisconnected) {
      probe_.failure = "probe state " + std::to_string(static_cast<int>(c.state())) +
                       ", reject " + std::to_string(c.reject_reason()) + ", disconnect " +
                       std::to_string(static_cast<int>(c.disconnect_reason()));
      probe_done_ = true;
    }
  }

  const HostileOptions& o_;
  RelayTarget* relay_;
  Clock::time_point t0_;
  std::string room_;
  asio::ip::address address_;
  uint32_t first_player_;
  ClientConfig cc_;
  std::vector<std::unique_ptr<Member>> members_;
  std::thread thread_;
  std::atomic<bool> stop_{false};

  std::mutex mu_;  // everything below, and the members' state, while the thread runs
  std::unordered_map<uint32_t, Member*> owners_;  // honest entity -> its member
  bool measuring_ = false;
  double phase_start_ = 0;
  std::vector<double> latencies_;
  bool probe_requested_ = false, probe_done_ = false, probe_join_sent_ = false;
  double probe_started_at_ = 0;
  uint32_t probes_ = 0;
  ProbeFigures probe_;
  std::unique_ptr<UdpSocket> probe_socket_;
  std::unique_ptr<Client> probe_client_;
};

void Member::OnEntityUpdated(const RemoteEntity& e) { room_->Received(*this, e); }

// The refusal families read from /metrics, with the shortened name of each series.
constexpr const char* kRefusalFamilies[] = {
    "edgephys_budget_refusals_total", "edgephys_requests_rejected_total",
    "edgephys_packets_rejected_total", "edgephys_entity_updates_rejected_total",
    "edgephys_disconnects_total"};

// `edgephys_budget_refusals_total{reason="player_particles"}` -> `budget_refusals{player_particles}`.
std::string ShortName(const std::string& series) {
  std::string name = series.substr(0, series.find('{'));
  if (name.rfind("edgephys_", 0) == 0) name = name.substr(9);
  if (name.size() > 6 && name.compare(name.size() - 6, 6, "_total") == 0) name.resize(name.size() - 6);
  const size_t q = series.find('"');
  const size_t q2 = q == std::string::npos ? q : series.find('"', q + 1);
  if (q2 == std::string::npos) return name;
  return name + "{" + series.substr(q + 1, q2 - q - 1) + "}";
}

class MetricsReader {
 public:
  explicit MetricsReader(std::string address) : address_(std::move(address)) {}
  // One scrape; empty with *error set if it failed.
  std::map<std::string, double> Read(std::string* error) const {
    std::string e;
    const std::string body = HttpGet(address_, "/metrics", 2.0, &e);
    if (body.empty()) {
      *error = "GET http://" + address_ + "/metrics: " + (e.empty() ? "empty" : e);
      return {};
    }
    return ParsePrometheusText(body);
  }
  const std::string& address() const { return address_; }

 private:
  std::string address_;
};

// The refusal series that moved between two scrapes (a disconnect by the client's own leave is
// no refusal and is left out); the PhyS step mean and the entity gauge go to `phase`.
void Differences(const std::map<std::string, double>& a, const std::map<std::string, double>& b,
                 HostilePhase* phase) {
  for (const auto& [series, value] : b) {
    bool refusal = false;
    for (const char* family : kRefusalFamilies) {
      refusal = refusal || series.rfind(std::string(family) + "{", 0) == 0;
    }
    if (!refusal || series.find("client_left") != std::string::npos) continue;
    auto it = a.find(series);
    const double d = value - (it == a.end() ? 0.0 : it->second);
    if (d > 0) phase->refusals[ShortName(series)] = d;
  }
  const double steps = SumSeries(b, "edgephys_physics_step_seconds_count") -
                       SumSeries(a, "edgephys_physics_step_seconds_count");
  const double secs = SumSeries(b, "edgephys_physics_step_seconds_sum") -
                      SumSeries(a, "edgephys_physics_step_seconds_sum");
  phase->physics_step_ms_mean = steps > 0 ? 1000.0 * secs / steps : kUnknown;
  phase->entities_gauge_end = SumSeries(b, "edgephys_entities");
}

bool OnIpv4Loopback(const Endpoint& e) {
  return e.address().is_v4() && e.address().to_v4().is_loopback();
}

void Sleep() { std::this_thread::sleep_for(std::chrono::microseconds(200)); }

HostileAttackResult RunOne(const HostileOptions& o, const HostileAttackInfo& info, size_t index,
                           RelayTarget& relay, const MetricsReader& metrics, Clock::time_point t0,
                           std::string* metrics_error) {
  HostileAttackResult r;
  r.attack = info.name;
  r.description = info.description;
  auto now = [&] { return std::chrono::duration<double>(Clock::now() - t0).count(); };
  const bool loopback = OnIpv4Loopback(relay.endpoint());
  const asio::ip::address any = asio::ip::make_address("0.0.0.0");
  const asio::ip::address honest_address = loopback ? asio::ip::make_address("127.0.0.1") : any;
  const std::string prefix = "hostile-" + std::to_string(index) + "-" + info.name;
  const uint32_t players = 10000 * static_cast<uint32_t>(index + 1);
  HonestRoom a(o, &relay, t0, prefix + "-a", honest_address, players + 1);
  HonestRoom b(o, &relay, t0, prefix + "-b", honest_address, players + 1001);
  auto progress = [&](const char* what) {
    if (o.progress) std::fprintf(stderr, "\r  hostile: %-8s %-10s t=%6.1f ", info.name, what, now());
  };
  progress("setup");
  for (HonestRoom* room : {&a, &b}) {
    if (std::string e = room->Start(); !e.empty()) {
      r.error = e;
      return r;
    }
  }
  if (!a.WaitReady(10) || !b.WaitReady(10)) {
    r.error = "the honest clients did not all join and see each other within 10 s";
    return r;
  }
  std::unique_ptr<HostileAttack> attack = info.make();
  AttackContext ctx;
  ctx.options = &o;
  ctx.relay = &relay;
  ctx.room = prefix + "-a";
  ctx.attacker_address = loopback ? asio::ip::make_address("127.0.2.1") : any;
  asio::error_code ec;
  ctx.flood_address = asio::ip::make_address(o.flood_address, ec);
  ctx.flood_possible = loopback && !ec;
  ctx.first_player = players + 5000;
  ctx.victim = a.victim();
  ctx.now = now;
  if (std::string e = attack->Prepare(ctx); !e.empty()) {
    r.error = e;
    return r;
  }
  r.ran = true;
  auto scrape = [&] {
    std::string e;
    auto s = metrics.Read(&e);
    if (!e.empty()) *metrics_error = e;
    return s;
  };
  // A phase: both honest rooms' figures and the metrics that moved from `begin` on.
  struct PhaseStart {
    decltype(scrape()) metrics;
    double at;
  };
  auto begin_phase = [&](const char* name) {
    progress(name);
    PhaseStart s{scrape(), now()};
    a.BeginPhase(s.at);
    b.BeginPhase(s.at);
    return s;
  };
  auto end_phase = [&](const char* name, const PhaseStart& begin, HostilePhase* phase) {
    const double end = now();
    phase->name = name;
    phase->seconds = end - begin.at;
    phase->same = a.EndPhase(end, &phase->probe);
    phase->other = b.EndPhase(end, nullptr);
    Differences(begin.metrics, scrape(), phase);
  };
  const double half = o.phase_s / 2;
  // Baseline: the attacker idles; the probe joins halfway.
  {
    for (double end = now() + 1.0; now() < end;) attack->Idle(now()), Sleep();  // settle
    const PhaseStart begin = begin_phase("baseline");
    const double start = begin.at;
    bool probe = false;
    while (true) {
      const double t = now();
      attack->Idle(t);
      if (!probe && t >= start + half) a.StartProbe(), probe = true;
      if (t >= start + o.phase_s && (a.ProbeFinished() || t >= start + o.phase_s + 10)) break;
      Sleep();
    }
    end_phase("baseline", begin, &r.baseline);
  }
  // Attack: lasts --phase after the attack has run its course (continuous attacks: from the
  // start; at most --attack-max in), the probe joining halfway through that.
  {
    const PhaseStart begin = begin_phase("attack");
    const double start = begin.at;
    double done_at = -1, probe_at = -1;
    while (true) {
      const double t = now();
      attack->Step(t);
      if (done_at < 0 && (attack->Done(t) || t >= start + o.attack_max_s)) done_at = t;
      if (probe_at < 0 && done_at >= 0 && t >= done_at + half) a.StartProbe(), probe_at = t;
      if (probe_at >= 0 && t >= done_at + o.phase_s &&
          (a.ProbeFinished() || t >= done_at + o.phase_s + 10)) {
        break;
      }
      Sleep();
    }
    r.attack_done_s = done_at - start;
    end_phase("attack", begin, &r.attack_phase);
  }
  attack->Finish();
  r.notes = attack->Notes();
  auto ratio = [](double x, double y) { return y > 0 ? x / y : kUnknown; };
  r.same_ratio = ratio(r.attack_phase.same.rate, r.baseline.same.rate);
  r.other_ratio = ratio(r.attack_phase.other.rate, r.baseline.other.rate);
  return r;
}

}  // namespace

HostileResult RunHostile(const HostileOptions& o) {
  HostileResult result;
  const Clock::time_point t0 = Clock::now();
  std::unique_ptr<RelayTarget> relay;
  std::unique_ptr<MetricsExporter> exporter;
  std::string metrics_address;
  if (o.external.enabled()) {
    relay = std::make_unique<RelayTarget>(o.external, t0);
    metrics_address = relay->metrics_address();
  } else {
    RelayConfig config;  // the relay's defaults: limits, budgets, packet authentication
    config.secret = "edgephys-loadgen-hostile";
    config.room_defaults.tick_rate_hz = o.tick_rate_hz;
    if (o.physics_threads > 0) config.physics_threads = o.physics_threads;
    relay = std::make_unique<RelayTarget>(config, t0);
    auto started = MetricsExporter::Start("127.0.0.1:0", RelayMetrics(&relay->thread()->counters));
    if (!started.ok()) {
      result.metrics_error = "in-process exporter: " + started.status().ToString();
    } else {
      exporter = std::move(*started);
      metrics_address = "127.0.0.1:" + std::to_string(exporter->port());
    }
  }
  result.metrics = metrics_address.empty() || metrics_address == "off"
                       ? "none"
                       : "http://" + metrics_address + "/metrics" +
                             (o.external.enabled() ? "" : " (in-process exporter)");
  const MetricsReader metrics(metrics_address == "off" ? "" : metrics_address);
  for (size_t i = 0; i < o.attacks.size(); ++i) {
    const HostileAttackInfo* info = FindHostileAttack(o.attacks[i]);
    if (info == nullptr) continue;  // validated by the scenario
    result.attacks.push_back(RunOne(o, *info, i, *relay, metrics, t0, &result.metrics_error));
    // The next attack's rooms are new; the relay's are left to their idle TTL.
  }
  if (o.progress) std::fprintf(stderr, "\n");
  return result;
}

}  // namespace edgephys::loadgen
