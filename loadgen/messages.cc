#include "loadgen/messages.h"

#include <flatbuffers/flatbuffers.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/property_codec.h"
#include "protocol/udp_socket.h"

namespace edgephys::loadgen {
namespace {

using Clock = std::chrono::steady_clock;

// Payload: u32 sender index, u32 message number, then filler.
struct Bot final : ClientListener {
  uint32_t index = 0;
  std::unique_ptr<UdpSocket> socket;
  std::unique_ptr<Client> client;
  bool counting = false;
  uint64_t received = 0;          // copies received while counting
  uint64_t refusals = 0;          // Error events
  uint64_t property_changes = 0;  // PropertyChanged events
  uint32_t sent_total = 0;        // messages sent since joining
  // Per sender: the next message number expected (reliable mode: all arrive, in order).
  std::vector<uint32_t> next_from;
  uint64_t received_total = 0, duplicates = 0;
  double credit = 0;              // messages due and not yet sent

  void OnMessage(uint32_t, std::span<const uint8_t> payload) override {
    Count(payload);
  }
  void OnUnreliableMessage(uint32_t, std::span<const uint8_t> payload) override {
    Count(payload);
  }
  void Count(std::span<const uint8_t> payload) {
    if (counting) ++received;
    if (payload.size() < 8) return;
    uint32_t from = 0, number = 0;
    std::memcpy(&from, payload.data(), 4);
    std::memcpy(&number, payload.data() + 4, 4);
    if (from >= next_from.size()) return;
    ++received_total;
    if (number < next_from[from]) ++duplicates;
    next_from[from] = std::max(next_from[from], number + 1);
  }
  void OnError(uint16_t, uint32_t, std::string_view) override { ++refusals; }
  void OnPropertyChanged(const PropertyRecord&) override { ++property_changes; }
};

struct Bots {
  explicit Bots(const MessagesOptions& o) : o_(o) {}
  std::unique_ptr<Bot> Add(const RelayTarget& relay, const std::string& room, uint32_t player,
                           double now) {
    auto b = std::make_unique<Bot>();
    b->index = player - 1;
    b->socket = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
    ClientConfig cc;
    cc.require_packet_auth = false;  // also --packet-auth false
    cc.handshake_timeout_s = 10;
    cc.decode_states = false;        // no entities here
    b->client = std::make_unique<Client>(cc, b->socket.get(), b.get());
    (void)b->client->Connect(ToRelayAddress(relay.endpoint()), relay.Token(room, player), now);
    return b;
  }
  const MessagesOptions& o_;
};

double Seconds(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

// Pumps `bots` every millisecond until `done()` or `timeout_s`.
template <typename Done, typename Each>
bool Pump(std::vector<std::unique_ptr<Bot>>& bots, Clock::time_point t0, double timeout_s,
          Done done, Each each) {
  const double end = Seconds(t0) + timeout_s;
  while (Seconds(t0) < end) {
    const double now = Seconds(t0);
    each(now);
    for (auto& b : bots) b->client->Update(now);
    if (done()) return true;
    std::this_thread::sleep_for(std::chrono::microseconds(500));
  }
  return done();
}

bool JoinAll(std::vector<std::unique_ptr<Bot>>& bots, Clock::time_point t0, const std::string& room) {
  auto all = [&](auto pred) {
    return std::all_of(bots.begin(), bots.end(), [&](auto& b) { return pred(*b->client); });
  };
  if (!Pump(bots, t0, 10, [&] { return all([](Client& c) { return c.state() == ClientState::kConnected; }); },
            [](double) {})) {
    return false;
  }
  for (auto& b : bots) (void)b->client->JoinRoom(room);
  return Pump(bots, t0, 10, [&] { return all([](Client& c) { return c.joined(); }); }, [](double) {});
}

void MeasureProperties(const MessagesOptions& o, const RelayTarget& relay, Clock::time_point t0,
                       MessagesResult* r) {
  Bots maker(o);
  std::vector<std::unique_ptr<Bot>> bots;
  bots.push_back(maker.Add(relay, "properties", 1001, Seconds(t0)));
  bots.push_back(maker.Add(relay, "properties", 1002, Seconds(t0)));
  if (!JoinAll(bots, t0, "properties")) return;
  Client& writer = *bots[0]->client;
  Client& listener = *bots[1]->client;
  const PropertyValue value = PropertyValue::Int64(1);
  const std::string key = "step";
  {
    flatbuffers::FlatBufferBuilder fbb(96);
    const auto k = fbb.CreateString(key);
    const auto v = WritePropertyValue(fbb, value);
    FinishControl(fbb, schema::CreatePropertySet(fbb, 0, k, v, false, 0,
                                                 schema::PropertyAuthority::Anyone, 1));
    r->property_message_bytes = fbb.GetSize();
  }
  (void)Pump(bots, t0, 0.5, [] { return false; }, [](double) {});  // join traffic done
  const auto sent = [&] { return static_cast<double>(writer.stats()->bytes_sent); };
  const auto received = [&] { return static_cast<double>(listener.stats()->bytes_received); };
  // Idle baseline, then the writes, over equal windows.
  const double idle_sent0 = sent(), idle_received0 = received();
  (void)Pump(bots, t0, o.property_seconds, [] { return false; }, [](double) {});
  const double idle_sent = sent() - idle_sent0, idle_received = received() - idle_received0;
  const double sent0 = sent(), received0 = received();
  const uint64_t changes0 = bots[0]->property_changes;
  const double start = Seconds(t0);
  uint64_t writes = 0;
  (void)Pump(bots, t0, o.property_seconds, [] { return false; }, [&](double now) {
    while (writes < (now - start) * o.property_hz) {
      PropertyValue v = PropertyValue::Int64(static_cast<int64_t>(writes));
      if (!writer.SetProperty(0, key, v, PropertyAuthority::kAnyone).ok()) break;
      ++writes;
    }
  });
  (void)Pump(bots, t0, 0.3, [] { return false; }, [](double) {});  // the last announcements
  const double w_sent = sent() - sent0, w_received = received() - received0;
  r->property_writes = bots[0]->property_changes - changes0;
  if (writes == 0) return;
  const double n = static_cast<double>(writes);
  // The write window ran 0.3 s longer (the tail); scale the idle baseline to it.
  const double scale = (o.property_seconds + 0.3) / o.property_seconds;
  r->property_sent_bytes = w_sent / n;
  r->property_received_bytes = w_received / n;
  r->property_sent_net_bytes = (w_sent - idle_sent * scale) / n;
  r->property_received_net_bytes = (w_received - idle_received * scale) / n;
}

}  // namespace

MessagesResult RunMessages(const MessagesOptions& o) {
  const Clock::time_point t0 = Clock::now();
  RelayConfig config;
  config.secret = "messages-" + std::to_string(SecureRandom64());
  config.max_clients = o.users + 64;
  config.room_defaults.capacity = o.users + 16;
  config.room_defaults.tick_rate_hz = o.tick_rate_hz;
  config.room_defaults.budgets.messages_per_s_per_player = 0;  // forwarding, not the limits
  config.room_defaults.budgets.message_bytes_per_s_per_player = 0;
  config.room_defaults.budgets.messages_per_s = 0;
  config.room_defaults.budgets.message_bytes_per_s = 0;
  config.packet_auth = o.packet_auth;
  config.limits.max_sessions_per_address = o.users + 64;  // every bot comes from 127.0.0.1
  config.limits.handshakes_per_s = 100000;
  config.limits.packets_per_s = 0;
  config.limits.bytes_per_s = 0;
  config.connection.timeout_s = 10;
  std::unique_ptr<RelayTarget> target = o.external.enabled()
                                            ? std::make_unique<RelayTarget>(o.external, t0)
                                            : std::make_unique<RelayTarget>(config, t0);
  RelayTarget& relay = *target;
  MessagesResult r;

  Bots maker(o);
  std::vector<std::unique_ptr<Bot>> bots;
  for (uint32_t i = 0; i < o.users; ++i) {
    bots.push_back(maker.Add(relay, "messages", i + 1, Seconds(t0)));
    bots.back()->next_from.assign(o.users, 0);
  }
  if (!JoinAll(bots, t0, "messages")) {
    if (o.progress) std::fprintf(stderr, "messages: not every bot joined\n");
  }
  for (auto& b : bots) r.joined += b->client->joined() ? 1 : 0;

  std::vector<uint8_t> payload(std::max<uint32_t>(o.payload_bytes, 8), 0x5a);
  bool counting = false;
  uint64_t sent_in_window = 0;
  double last = Seconds(t0);
  const auto send_due = [&](double now) {
    const double dt = now - last;
    last = now;
    for (auto& b : bots) {
      if (!b->client->joined()) continue;
      b->credit += dt * o.rate_hz;
      while (b->credit >= 1) {
        b->credit -= 1;
        std::memcpy(payload.data(), &b->index, 4);
        std::memcpy(payload.data() + 4, &b->sent_total, 4);
        const Status s = o.unreliable
                             ? b->client->SendMessageUnreliable(MessageTarget::kRoom, 0, payload)
                             : b->client->SendMessage(MessageTarget::kRoom, 0, payload);
        if (!s.ok()) {
          ++r.send_refused;
          continue;
        }
        ++b->sent_total;
        if (counting) ++sent_in_window;
      }
    }
  };
  (void)Pump(bots, t0, o.warmup_s, [] { return false; }, send_due);
  const RelayFigures before = relay.Read();
  for (auto& b : bots) b->counting = true;
  counting = true;
  const double window_start = Seconds(t0);
  (void)Pump(bots, t0, o.duration_s, [] { return false; }, send_due);
  const double window_end = Seconds(t0);
  const RelayFigures after = relay.Read();
  for (auto& b : bots) b->counting = false;
  counting = false;
  // Let everything sent arrive (reliable mode's completeness check).
  const auto expected = [&] {
    uint64_t n = 0;
    for (auto& b : bots) n += b->sent_total;
    return n * r.joined;
  };
  (void)Pump(bots, t0, 3.0, [&] {
    uint64_t got = 0;
    for (auto& b : bots) got += b->received_total;
    return o.unreliable || got >= expected();
  }, [](double) {});

  r.window_s = window_end - window_start;
  r.sent = sent_in_window;
  for (auto& b : bots) {
    r.received += b->received;
    r.relay_refusals += b->refusals;
    r.received_total += b->received_total;
    r.duplicates += b->duplicates;
  }
  r.expected_total = expected();
  r.sent_per_s = static_cast<double>(r.sent) / r.window_s;
  r.delivered_per_s = static_cast<double>(r.received) / r.window_s;
  r.relay_egress_bytes_per_s = (after.bytes_sent - before.bytes_sent) / r.window_s;
  if (std::isfinite(after.cpu_s) && std::isfinite(before.cpu_s)) {
    r.relay_cpu = (after.cpu_s - before.cpu_s) / r.window_s;
    if (r.relay_cpu > 0) {
      r.delivered_per_core_s = r.delivered_per_s / r.relay_cpu;
      r.accepted_per_core_s = r.sent_per_s / r.relay_cpu;
    }
  }
  bots.clear();  // their sessions time out; the property rooms are separate
  MeasureProperties(o, relay, t0, &r);
  return r;
}

}  // namespace edgephys::loadgen
