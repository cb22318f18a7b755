// message_fuzz: every FlatBuffers control message handler, relay side and client side.
//
// Input: u8 mode | records (u8 tag | u16 length | bytes), at most kMaxRecords. Each record's
// bytes also go through VerifyControlMessage directly. By mode % 3:
//   0: relay, embedded PhyS. Real clients A (player 1) and C (player 2) have joined room
//      "fuzz". By tag % 4 the bytes are sent as a reliable message by A / by C (so the relay's
//      JoinRoom, LeaveRoom, Spawn -> PhyS validation and Bullet world, Despawn, Grab, Release,
//      AppMessage (room messages, their budgets and forwarding), PropertySet (properties:
//      compare-and-set, authority, budgets, value checks), OwnershipRequest (requests, hand
//      overs, releases, takeover, refusals), Worker* handlers run on
//      them), as an unreliable payload by A (states; format 15: unreliable messages, their
//      budgets and forwarding), or pump bytes[0] % 16 extra steps.
//   1: relay, remote PhyS. A real PhyS worker W (Client + PhysicsWorker, worker token) is
//      attached before A joins, so A's physics spawns go to W. By tag % 4: a reliable message
//      from A / from W (WorkerResult, WorkerHello, ...), an unreliable payload from W (worker
//      states, format 6 / 8 soft chunks) / from A.
//   2: client SDK. A fake relay completes the handshake by hand and then sends, on a real
//      server-side Connection, the records: tag % 2 == 0 a reliable message (Joined, Spawn,
//      Despawn, PhysicsEvent, Error, AppMessage, PropertyChanged, PropertyConflict,
//      OwnershipChanged, Worker* ->
//      the PhysicsWorker listener, ...),
//      else an unreliable payload (state formats 1..5; format 15 unreliable messages). mode bit 2: a valid Joined with state format
//      1 + (mode >> 3) % 4 is sent first.
// Everything is pumped with a fake clock after each record.
#include <cstddef>
#include <cstdint>

#include "client/client_endpoint.h"
#include "physics_backend/worker.h"
#include "protocol/delta_codec.h"
#include "tests/fuzz/fuzz_world.h"
#include "client/client_testing.h"

namespace edgephys::fuzz {
namespace {

constexpr size_t kMaxRecords = 48;

void VerifyDirectly(std::span<const uint8_t> bytes) {
  const schema::ControlMessage* msg = VerifyControlMessage(bytes);
  if (msg != nullptr) (void)schema::EnumNameBody(msg->body_type());
}

void RunRelayEmbedded(Reader& in) {
  World world;
  Client& a = world.AddClient(1, kDefaultPermissions);
  Client& c = world.AddClient(2, kDefaultPermissions);
  if (!world.ConnectAndJoin(a) || !world.ConnectAndJoin(c)) std::abort();
  for (size_t i = 0; i < kMaxRecords && !in.empty(); ++i) {
    const uint8_t tag = in.U8();
    auto bytes = in.Bytes(in.U16());
    VerifyDirectly(bytes);
    int steps = 2;
    switch (tag % 4) {
      case 0: (void)ClientTesting::SendReliableUnchecked(a, bytes); break;
      case 1: (void)ClientTesting::SendReliableUnchecked(c, bytes); break;
      case 2: (void)ClientTesting::SendUnreliableRaw(a, bytes, world.now()); break;
      case 3: steps += bytes.empty() ? 0 : bytes[0] % 16; break;
    }
    for (int s = 0; s < steps; ++s) world.Step();
  }
  for (int s = 0; s < 4; ++s) world.Step();
}

void RunRelayRemote(Reader& in) {
  World world;
  PhysicsWorker worker{physics::PhysicsConfig{}};
  Client& w = world.AddClient(100, kPermissionWorker | kDefaultPermissions, &worker);
  worker.Attach(&w);
  auto step = [&] {
    world.Step();
    worker.Update(world.now());
  };
  for (int s = 0; s < 20 && w.state() != ClientState::kConnected; ++s) step();
  for (int s = 0; s < 4; ++s) step();  // WorkerHello reaches the relay
  Client& a = world.AddClient(1, kDefaultPermissions);
  for (int s = 0; s < 20 && a.state() != ClientState::kConnected; ++s) step();
  if (a.state() != ClientState::kConnected || !a.JoinRoom(kFuzzRoom).ok()) std::abort();
  for (int s = 0; s < 20 && !a.joined(); ++s) step();
  if (!a.joined()) std::abort();

  for (size_t i = 0; i < kMaxRecords && !in.empty(); ++i) {
    const uint8_t tag = in.U8();
    auto bytes = in.Bytes(in.U16());
    VerifyDirectly(bytes);
    switch (tag % 4) {
      case 0: (void)ClientTesting::SendReliableUnchecked(a, bytes); break;
      case 1: (void)ClientTesting::SendReliableUnchecked(w, bytes); break;
      case 2: (void)ClientTesting::SendUnreliableRaw(w, bytes, world.now()); break;
      case 3: (void)ClientTesting::SendUnreliableRaw(a, bytes, world.now()); break;
    }
    step();
    step();
  }
  for (int s = 0; s < 4; ++s) step();
}

// The relay end of one client connection, driven by hand.
class FakeRelay final : public PacketWriter, public ConnectionHandler {
 public:
  FakeRelay(InMemoryNetwork& net, const Endpoint& at) : socket_(net.CreateSocket(at)) {}

  // Answers the client's Hello and Connect; true once Accept is sent.
  bool Handshake(double now) {
    Endpoint from;
    size_t n;
    while ((n = socket_->ReceiveFrom(&from, buffer_)) != 0) {
      PacketPrefix prefix{};
      DropReason reason{};
      std::span<const uint8_t> packet(buffer_.data(), std::min(n, buffer_.size()));
      if (!ParsePacketPrefix(packet, &prefix, &reason)) continue;
      flatbuffers::FlatBufferBuilder fbb(128);
      if (prefix.type == PacketType::kHello) {
        const uint8_t cookie[kCookieSize] = {1, 2, 3};
        FinishControl(fbb, schema::CreateChallenge(fbb, fbb.CreateVector(cookie, kCookieSize)));
        auto reply = BuildHandshakePacket(PacketType::kChallenge, fbb);
        (void)socket_->SendTo(from, reply);
      } else if (prefix.type == PacketType::kConnect) {
        FinishControl(fbb, schema::CreateAccept(fbb, kConnectionId, kPlayer, 100, 5000));
        auto reply = BuildHandshakePacket(PacketType::kAccept, fbb);
        (void)socket_->SendTo(from, reply);
        client_ = from;
        connection_ = std::make_unique<Connection>(kConnectionId, ConnectionConfig{}, now);
        return true;
      }
    }
    return false;
  }

  // Receives the client's packets and sends ours.
  void Pump(double now) {
    Endpoint from;
    size_t n;
    while ((n = socket_->ReceiveFrom(&from, buffer_)) != 0) {
      if (n > buffer_.size() || !connection_ || !connection_->connected()) continue;
      std::span<const uint8_t> packet(buffer_.data(), n);
      PacketPrefix prefix{};
      DropReason reason{};
      if (!ParsePacketPrefix(packet, &prefix, &reason)) continue;
      if (prefix.type == PacketType::kData || prefix.type == PacketType::kDisconnect) {
        (void)connection_->ProcessPacket(packet, now, *this);
      }
    }
    if (connection_) connection_->Update(now, *this);
  }

  Connection* connection() { return connection_.get(); }

  void WritePacket(std::span<const uint8_t> packet) override { (void)socket_->SendTo(client_, packet); }
  void OnReliableMessage(std::span<const uint8_t>) override {}
  void OnUnreliablePayload(uint16_t, std::span<const uint8_t>) override {}

  static constexpr uint32_t kConnectionId = 0x0badf00d;
  static constexpr uint32_t kPlayer = 7;

 private:
  std::unique_ptr<DatagramSocket> socket_;
  std::vector<uint8_t> buffer_ = std::vector<uint8_t>(kMaxPacketSize + 512);
  Endpoint client_;
  std::unique_ptr<Connection> connection_;
};

std::vector<uint8_t> JoinedMessage(uint8_t format) {
  flatbuffers::FlatBufferBuilder fbb(256);
  schema::Vec3 bmin(-1000, -1000, -1000), bmax(1000, 1000, 1000);
  auto room = fbb.CreateString(kFuzzRoom);
  schema::JoinedBuilder jb(fbb);
  jb.add_room(room);
  jb.add_player_id(FakeRelay::kPlayer);
  jb.add_entity_id_base(kEntityIdBlock);  // slot 1
  jb.add_tick_rate_hz(30);
  jb.add_state_format(format);
  jb.add_position_step_m(0.001f);
  jb.add_rotation_bound_deg(0.1f);
  jb.add_bounds_min(&bmin);
  jb.add_bounds_max(&bmax);
  FinishControl(fbb, jb.Finish());
  return std::vector<uint8_t>(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
}

void RunClient(Reader& in, uint8_t mode) {
  InMemoryNetwork net(1024);
  const Endpoint relay_at = Ep("10.0.0.1", 7777);
  FakeRelay relay(net, relay_at);
  auto socket = net.CreateSocket(Ep("10.0.0.2", 40000));
  PhysicsWorker worker{physics::PhysicsConfig{}};
  // The fake relay's Accept carries no packet key (it fuzzes messages, not the seal, which
  // packet_fuzz covers): the client must accept an unsealed relay.
  ClientConfig config;
  config.require_packet_auth = false;
  Client client(config, socket.get(), &worker);
  worker.Attach(&client);
  double now = 1.0;
  auto token = MintToken(FakeRelay::kPlayer, kDefaultPermissions);
  (void)client.Connect(ToRelayAddress(relay_at), token, now);
  bool accepted = false;
  for (int i = 0; i < 10 && client.state() != ClientState::kConnected; ++i) {
    accepted = relay.Handshake(now) || accepted;
    now += World::kDt;
    client.Update(now);
  }
  if (!accepted || client.state() != ClientState::kConnected) std::abort();

  auto step = [&] {
    now += World::kDt;
    relay.Pump(now);
    client.Update(now);
    worker.Update(now);
  };
  if (mode & 4) {
    auto joined = JoinedMessage(static_cast<uint8_t>(1 + (mode >> 3) % 4));
    (void)relay.connection()->SendReliable(joined);
    step();
    step();
  }
  for (size_t i = 0; i < kMaxRecords && !in.empty(); ++i) {
    const uint8_t tag = in.U8();
    auto bytes = in.Bytes(in.U16());
    VerifyDirectly(bytes);
    if (!relay.connection()->connected()) break;
    if (tag % 2 == 0) {
      (void)relay.connection()->SendReliable(bytes);
    } else {
      (void)relay.connection()->SendUnreliable(bytes, now, relay);
    }
    step();
    step();
  }
  for (int s = 0; s < 3; ++s) step();
  for (const auto& [id, e] : client.entities()) {
    EDGEPHYS_FUZZ_CHECK(e.id == id);
  }
}

}  // namespace
}  // namespace edgephys::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace edgephys::fuzz;
  Reader in(data, size);
  const uint8_t mode = in.U8();
  switch (mode % 3) {
    case 0: RunRelayEmbedded(in); break;
    case 1: RunRelayRemote(in); break;
    case 2: RunClient(in, mode); break;
  }
  return 0;
}
