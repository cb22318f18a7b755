// The client SDK's per-received-state path: Client::Update() receiving state packets for a
// room of `entities` remote entities (format 1, 36 states per packet, all spawned) and 4
// entities of its own (not published: Update() does no sending work but keep-alives). Second
// argument: 0 = no listener (the SDK alone: connection, decode, entity table), 1 = a listener
// that does what a renderer or edgephys-loadgen ccu does on every update, one
// SnapshotBuffer::Insert for the entity. Items are received entity states.
//
// The relay is faked: a FakeSocket hands the client a Challenge, an Accept, then the data
// packets of a server-side Connection (Joined, the spawns, the state packets). One state packet
// per room slice is built up front; each iteration rewrites its unreliable sequence number and
// delivers it, so the client does the full receive work (connection, decode, entity update,
// listener) and nothing else.
#include <benchmark/benchmark.h>

#include <cmath>
#include <deque>
#include <unordered_map>
#include <vector>

#include "client/client.h"
#include "client/client_endpoint.h"
#include "client/snapshot_buffer.h"
#include "protocol/byte_io.h"
#include "protocol/testing/connection_doubles.h"
#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"

namespace edgephys {
namespace {

using Bytes = std::vector<uint8_t>;

constexpr uint32_t kConnectionId = 0x51;
constexpr uint32_t kPlayerId = 1;
constexpr uint32_t kFirstRemoteId = 2 * 65536;  // another player's id block
constexpr size_t kStatesPerPacket = 36;

class FakeSocket final : public DatagramSocket {
 public:
  explicit FakeSocket(const Endpoint& server) : server_(server) {}
  Status SendTo(const Endpoint&, std::span<const uint8_t> data) override {
    if (keep_sent) sent.emplace_back(data.begin(), data.end());
    return Status::Ok();
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    if (inbox_.empty()) return 0;
    const Bytes& p = inbox_.front();
    const size_t n = std::min(p.size(), buffer.size());
    std::copy_n(p.begin(), n, buffer.begin());
    *from = server_;
    const size_t size = p.size();
    inbox_.pop_front();
    return size;
  }
  Endpoint LocalEndpoint() const override { return Endpoint(); }
  void Push(std::span<const uint8_t> packet) { inbox_.emplace_back(packet.begin(), packet.end()); }

  bool keep_sent = true;
  std::vector<Bytes> sent;

 private:
  Endpoint server_;
  std::deque<Bytes> inbox_;
};

using edgephys::testing::CapturingWriter;
using edgephys::testing::NullHandler;

// What a renderer (or edgephys-loadgen ccu) does per update: feed the entity's jitter buffer.
class BufferingListener final : public ClientListener {
 public:
  explicit BufferingListener(const double* now) : now_(now) {}
  void OnEntityUpdated(const RemoteEntity& e) override {
    if (!enabled) return;
    SnapshotBuffer& buffer = buffers_[e.id];
    buffer.Insert({.sender_time_s = e.state_time_ms / 1000.0,
                   .position = e.state.position,
                   .rotation = e.state.rotation},
                  *now_);
  }

 private:
  const double* now_;
  std::unordered_map<uint32_t, SnapshotBuffer> buffers_;

 public:
  bool enabled = true;
};

// A client joined to a room of `entities` spawned remote entities, and the state packets that
// cover the room (each with its sequence at kPacketPrefixSize, rewritten per delivery).
struct Fixture {
  Endpoint server{asio::ip::make_address("127.0.0.1"), 7777};
  FakeSocket socket{server};
  double now = 0;
  BufferingListener listener{&now};
  Client client{ClientConfig{}, &socket, &listener};
  Connection relay{kConnectionId, ConnectionConfig{}, 0};
  NullHandler relay_handler;
  CapturingWriter relay_out;
  std::vector<Bytes> state_packets;
  uint16_t sequence = 0;

  explicit Fixture(size_t entities) {
    JoinToken t;  // a client token; the scripted relay never reads it
    t.room = "r";
    t.player_id = 1;
    t.expiry_unix_s = 4'000'000'000;
    const Bytes token = *SignJoinToken(t, "scripted");
    (void)client.Connect(ToRelayAddress(server), token, now);
    {
      flatbuffers::FlatBufferBuilder fbb(64);
      const Bytes cookie(kCookieSize, 2);
      FinishControl(fbb, schema::CreateChallenge(fbb, fbb.CreateVector(cookie)));
      socket.Push(BuildHandshakePacket(PacketType::kChallenge, fbb));
    }
    client.Update(now);
    {
      flatbuffers::FlatBufferBuilder fbb(64);
      FinishControl(fbb, schema::CreateAccept(fbb, kConnectionId, kPlayerId, 1000, 60000));
      socket.Push(BuildHandshakePacket(PacketType::kAccept, fbb));
    }
    client.Update(now);
    {
      flatbuffers::FlatBufferBuilder fbb(64);
      FinishControl(fbb, schema::CreateJoined(fbb, fbb.CreateString("bench"), kPlayerId, 65536));
      Send(fbb);
    }
    for (size_t i = 0; i < entities; ++i) {
      flatbuffers::FlatBufferBuilder fbb(256);
      EntitySpec spec;
      spec.id = kFirstRemoteId + static_cast<uint32_t>(i);
      spec.owner = 2;
      FinishControl(fbb, schema::CreateSpawn(fbb, AddContainer(fbb, spec)));
      Send(fbb);
      if (i % 256 == 255) Pump();
    }
    Pump();
    Pump();
    if (!client.joined() || client.entities().size() != entities) std::abort();
    // Like an edgephys-loadgen ccu bot: a head, two hands and a box of its own.
    for (int k = 0; k < 4; ++k) {
      if (!client.Spawn({.position = {0, 1, 0}}).ok()) std::abort();
    }
    Pump();

    // State packets: the room in slices of kStatesPerPacket, at "relay time" 0.
    Bytes payload(kMaxUnreliablePayload);
    FloatStateEncoder encoder;
    for (size_t first = 0; first < entities; first += kStatesPerPacket) {
      encoder.Begin(payload, 0);
      for (size_t i = first; i < std::min(entities, first + kStatesPerPacket); ++i) {
        const float x = static_cast<float>(i);
        if (!encoder.Add({kFirstRemoteId + static_cast<uint32_t>(i), {x, 1, 0}, {}})) std::abort();
      }
      const size_t size = encoder.Finish();
      relay_out.packets.clear();
      if (!relay.SendUnreliable({payload.data(), size}, now, relay_out).ok()) std::abort();
      state_packets.push_back(relay_out.packets.back());
    }
    sequence = LoadU16LE(state_packets.back().data() + kPacketPrefixSize);
    socket.keep_sent = false;
  }

  void Send(flatbuffers::FlatBufferBuilder& fbb) {
    if (!relay.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()}).ok()) std::abort();
  }

  // Relay -> client and client -> relay until both are quiet.
  void Pump() {
    for (int round = 0; round < 64; ++round) {
      now += 0.01;
      relay_out.packets.clear();
      relay.Update(now, relay_out);
      for (const Bytes& p : relay_out.packets) socket.Push(p);
      socket.sent.clear();
      client.Update(now);
      for (const Bytes& p : socket.sent) (void)relay.ProcessPacket(p, now, relay_handler);
      if (relay_out.packets.empty() && round > 2) break;
    }
  }

  // Delivers the i-th state packet with the next sequence and a relay time 1/30 s later per
  // round of the room, then runs one client Update.
  void Deliver(size_t i) {
    Bytes& p = state_packets[i];
    StoreU16LE(p.data() + kPacketPrefixSize, ++sequence);
    if (i == 0) {
      now += 1.0 / 30;
      // Relay time (u32 ms) sits right after the format byte of the state payload: bump it so
      // that each round of the room is a new snapshot for the jitter buffers.
      const size_t payload_at = kConnectionHeaderSize + 3;
      const uint32_t time_ms = static_cast<uint32_t>(now * 1000.0);
      for (Bytes& q : state_packets) StoreU32LE(q.data() + payload_at + 1, time_ms);
    }
    socket.Push(p);
    client.Update(now);
  }
};

void BM_ClientReceive(benchmark::State& state) {
  const size_t entities = static_cast<size_t>(state.range(0));
  Fixture f(entities);
  f.listener.enabled = state.range(1) != 0;
  size_t i = 0;
  int64_t states = 0;
  for (auto _ : state) {
    f.Deliver(i);
    states += static_cast<int64_t>(std::min(kStatesPerPacket, entities - i * kStatesPerPacket));
    if (++i == f.state_packets.size()) i = 0;
  }
  if (f.client.state() != ClientState::kConnected) state.SkipWithError("client disconnected");
  state.SetItemsProcessed(states);
}
BENCHMARK(BM_ClientReceive)->ArgsProduct({{36, 396, 3600}, {0, 1}});

}  // namespace
}  // namespace edgephys

BENCHMARK_MAIN();
