// Client's handling of received entity states, against a scripted relay (a server-side
// Connection behind a fake socket): which states create or update entities, which are ignored
// (own entities, despawned ids, invalid values), and when OnEntityUpdated fires. The end-to-end
// behaviour with a real relay is covered by tests/integration.
#include "client/client.h"

#include <gtest/gtest.h>
#include <time.h>

#include <algorithm>
#include <deque>
#include <limits>
#include <memory>
#include <vector>

#include "client/client_endpoint.h"
#include "client/client_testing.h"
#include "client/state_decoder_plugin.h"
#include "protocol/testing/connection_doubles.h"
#include "protocol/container_builder.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/udp_socket.h"

namespace edgephys {
namespace {

using Bytes = std::vector<uint8_t>;

constexpr uint32_t kConnectionId = 0x77;
constexpr uint32_t kPlayerId = 1;
constexpr uint32_t kOwnBase = kEntityIdBlock;      // this client's id block (slot 1)
constexpr uint32_t kOtherBase = 3 * kEntityIdBlock;  // another player's block (slot 3)

// CLOCK_REALTIME in seconds, the clock of arrival times.
double RealtimeNow() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<double>(now.tv_sec) + now.tv_nsec * 1e-9;
}

class FakeSocket final : public DatagramSocket {
 public:
  // How the socket answers EnableArrivalTimes(): not supported (the default of a
  // DatagramSocket), with `scripted_arrival_unix_s` for every datagram, or by carrying the
  // client's datagrams over real loopback UDP so that the kernel stamps them.
  enum class Stamps { kNone, kScripted, kKernel };

  explicit FakeSocket(const Endpoint& server) : server_(server) {}
  Status SendTo(const Endpoint&, std::span<const uint8_t> data) override {
    sent.emplace_back(data.begin(), data.end());
    return Status::Ok();
  }
  size_t ReceiveFrom(Endpoint* from, std::span<uint8_t> buffer) override {
    if (inbox.empty()) return 0;
    const Bytes p = std::move(inbox.front());
    inbox.pop_front();
    std::copy_n(p.begin(), std::min(p.size(), buffer.size()), buffer.begin());
    *from = server_;
    return p.size();
  }
  Endpoint LocalEndpoint() const override { return Endpoint(); }

  void SetStamps(Stamps stamps) {
    stamps_ = stamps;
    if (stamps != Stamps::kKernel) return;
    const Endpoint loopback(asio::ip::make_address("127.0.0.1"), 0);
    wire_out_ = std::move(*UdpSocket::Open(loopback));
    wire_in_ = std::move(*UdpSocket::Open(loopback));
  }
  bool EnableArrivalTimes() override {
    arrival_times_requested = true;
    if (stamps_ == Stamps::kKernel) return wire_in_->EnableArrivalTimes();
    return stamps_ == Stamps::kScripted;
  }
  size_t ReceiveFromTimed(Endpoint* from, std::span<uint8_t> buffer,
                          double* arrival_unix_s) override {
    switch (stamps_) {
      case Stamps::kNone:
        return DatagramSocket::ReceiveFromTimed(from, buffer, arrival_unix_s);
      case Stamps::kScripted:
        *arrival_unix_s = scripted_arrival_unix_s;
        return ReceiveFrom(from, buffer);
      case Stamps::kKernel:
        break;
    }
    for (; !inbox.empty(); inbox.pop_front()) {
      EXPECT_TRUE(wire_out_->SendTo(wire_in_->LocalEndpoint(), inbox.front()).ok());
      ++in_flight_;
    }
    if (in_flight_ > 0) wire_in_->WaitReadable(5.0);  // loopback; only guards against a stall
    Endpoint sender;
    const size_t n = wire_in_->ReceiveFromTimed(&sender, buffer, arrival_unix_s);
    if (n == 0) return 0;
    --in_flight_;
    *from = server_;
    return n;
  }

  std::deque<Bytes> inbox;
  std::vector<Bytes> sent;
  bool arrival_times_requested = false;
  double scripted_arrival_unix_s = 1.6e9;

 private:
  Endpoint server_;
  Stamps stamps_ = Stamps::kNone;
  std::unique_ptr<UdpSocket> wire_out_, wire_in_;
  size_t in_flight_ = 0;
};

using edgephys::testing::CapturingWriter;

// The scripted relay's side: which of its packets the client acknowledged.
class AckRecorder final : public ConnectionHandler {
 public:
  void OnReliableMessage(std::span<const uint8_t>) override {}
  void OnUnreliablePayload(uint16_t, std::span<const uint8_t>) override {}
  void OnPacketAcked(uint16_t sequence) override { acked.push_back(sequence); }
  bool Acked(uint16_t sequence) const {
    return std::find(acked.begin(), acked.end(), sequence) != acked.end();
  }
  std::vector<uint16_t> acked;
};

class RecordingListener final : public ClientListener {
 public:
  void OnEntitySpawned(const RemoteEntity& e) override { spawned.push_back(e.id); }
  void OnEntityUpdated(const RemoteEntity& e) override {
    updated.push_back(e.id);
    last_x = e.state.position.x;
    last_arrival_unix_s = e.arrival_unix_s;
    last_update_read_unix_s = RealtimeNow();
  }
  void OnEntityDespawned(uint32_t id) override { despawned.push_back(id); }
  std::vector<uint32_t> spawned, updated, despawned;
  float last_x = 0;
  double last_arrival_unix_s = 0;      // RemoteEntity::arrival_unix_s in the last update
  double last_update_read_unix_s = 0;  // CLOCK_REALTIME when that update was reported
};

// A client token for the scripted relay (which checks nothing: it never reads the token).
Bytes ScriptedToken() {
  JoinToken t;
  t.room = "r";
  t.player_id = 1;
  t.expiry_unix_s = 4'000'000'000;
  return *SignJoinToken(t, "scripted");
}

// Format 1 (exact floats) for the scripted relay's states: the SDK decodes only the relay's
// formats (9, 2, 11), so these tests give the client a plug-in for the simplest one.
class Format1Decoder final : public StateDecoderPlugin {
 public:
  Status Decode(std::span<const uint8_t> payload, const Known&, StateBatch* batch) const override {
    return DecodeStateBatch(payload, batch);
  }
};

// A client joined to room "r" (own block kOwnBase, state format 1: Joined's default) through
// a scripted relay.
class ClientReceiveTest : public ::testing::Test {
 protected:
  explicit ClientReceiveTest(const ClientConfig& config = WithFormat1(ClientConfig{}))
      : client_(Unsealed(config), &socket_, &listener_) {}
  static ClientConfig WithFormat1(ClientConfig config) {
    config.state_decoder = std::make_shared<Format1Decoder>();
    return config;
  }
  // The scripted relay does not seal: its Accept carries no key.
  static ClientConfig Unsealed(ClientConfig config) {
    config.require_packet_auth = false;
    return config;
  }

  void SetUp() override {
    ASSERT_TRUE(client_.Connect(ToRelayAddress(server_), ScriptedToken(), now_).ok());
    flatbuffers::FlatBufferBuilder challenge(64);
    FinishControl(challenge, schema::CreateChallenge(
                                 challenge, challenge.CreateVector(Bytes(kCookieSize, 2))));
    socket_.inbox.push_back(BuildHandshakePacket(PacketType::kChallenge, challenge));
    client_.Update(now_);
    flatbuffers::FlatBufferBuilder accept(64);
    FinishControl(accept, schema::CreateAccept(accept, kConnectionId, kPlayerId, 1000, 60000));
    socket_.inbox.push_back(BuildHandshakePacket(PacketType::kAccept, accept));
    client_.Update(now_);
    ASSERT_EQ(client_.state(), ClientState::kConnected);
    flatbuffers::FlatBufferBuilder joined(64);
    FinishControl(joined,
                  schema::CreateJoined(joined, joined.CreateString("r"), kPlayerId, kOwnBase));
    SendReliable(joined);
    Pump();
    ASSERT_TRUE(client_.joined());
    ASSERT_EQ(client_.entity_id_base(), kOwnBase);
  }

  void SendReliable(flatbuffers::FlatBufferBuilder& fbb) {
    ASSERT_TRUE(relay_.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()}).ok());
  }

  void Spawn(uint32_t id, float x = 0) {
    flatbuffers::FlatBufferBuilder fbb(256);
    EntitySpec spec;
    spec.id = id;
    spec.owner = 2;
    spec.position = {x, 0, 0};
    FinishControl(fbb, schema::CreateSpawn(fbb, AddContainer(fbb, spec)));
    SendReliable(fbb);
    Pump();
  }

  void Despawn(uint32_t id) {
    flatbuffers::FlatBufferBuilder fbb(32);
    FinishControl(fbb, schema::CreateDespawn(fbb, id));
    SendReliable(fbb);
    Pump();
  }

  // One state packet (format 1) with these states, relay time `time_ms`.
  void SendStates(const std::vector<EntityState>& states, uint32_t time_ms = 1000) {
    Bytes payload(kMaxUnreliablePayload);
    FloatStateEncoder encoder;
    encoder.Begin(payload, time_ms);
    for (const EntityState& s : states) ASSERT_TRUE(encoder.Add(s));
    const size_t size = encoder.Finish();
    payload.resize(size);
    SendPayload(payload);
  }

  // One unreliable packet carrying `payload` as it is (any bytes).
  void SendPayload(const Bytes& payload) {
    relay_out_.packets.clear();
    auto sequence = relay_.SendUnreliable({payload.data(), payload.size()}, now_, relay_out_);
    ASSERT_TRUE(sequence.ok());
    last_sequence_ = *sequence;
    for (const Bytes& p : relay_out_.packets) socket_.inbox.push_back(p);
    Pump();
  }

  // Relay <-> client until the relay has nothing more to send.
  void Pump() {
    for (int round = 0; round < 16; ++round) {
      now_ += 0.01;
      relay_out_.packets.clear();
      relay_.Update(now_, relay_out_);
      for (const Bytes& p : relay_out_.packets) socket_.inbox.push_back(p);
      socket_.sent.clear();
      client_.Update(now_);
      // The scripted relay only needs the client's acks; the tests check the client's side.
      for (const Bytes& p : socket_.sent) (void)relay_.ProcessPacket(p, now_, relay_handler_);
      if (relay_out_.packets.empty() && socket_.inbox.empty() && round > 1) break;
    }
  }

  static EntityState At(uint32_t id, float x) { return {id, {x, 0, 0}, {}}; }

  Endpoint server_{asio::ip::make_address("127.0.0.1"), 7777};
  FakeSocket socket_{server_};
  RecordingListener listener_;
  double now_ = 0;
  Client client_;
  Connection relay_{kConnectionId, ConnectionConfig{}, 0};
  AckRecorder relay_handler_;
  uint16_t last_sequence_ = 0;  // of the last SendPayload / SendStates
  CapturingWriter relay_out_;
};

TEST_F(ClientReceiveTest, StateUpdatesASpawnedEntityAndNotifies) {
  const uint32_t id = kOtherBase + 5;
  Spawn(id, 1.0f);
  ASSERT_EQ(listener_.spawned, std::vector<uint32_t>{id});
  ASSERT_NE(client_.FindEntity(id), nullptr);
  EXPECT_FALSE(client_.FindEntity(id)->has_state);
  EXPECT_EQ(client_.FindEntity(id)->state.position.x, 1.0f);  // the spawn's transform

  SendStates({At(id, 2.0f)}, 1234);
  ASSERT_EQ(listener_.updated, std::vector<uint32_t>{id});
  EXPECT_EQ(listener_.last_x, 2.0f);
  const RemoteEntity* e = client_.FindEntity(id);
  ASSERT_NE(e, nullptr);
  EXPECT_TRUE(e->has_state);
  EXPECT_TRUE(e->spawned);
  EXPECT_EQ(e->id, id);
  EXPECT_EQ(e->state.position.x, 2.0f);
  EXPECT_EQ(e->state_time_ms, 1234u);
  EXPECT_EQ(client_.entities().size(), 1u);
  EXPECT_TRUE(relay_handler_.Acked(last_sequence_));
}

// Without a decoder for it, a format the SDK does not carry is refused and counted, and neither
// a malformed payload of a format it does carry nor one of another room's format applies.
class ClientRefusalTest : public ClientReceiveTest {
 protected:
  ClientRefusalTest() : ClientReceiveTest(ClientConfig{}) {}
};

TEST_F(ClientRefusalTest, StatesOfAFormatTheSdkDoesNotDecodeAreRefusedAndCounted) {
  const uint32_t id = kOtherBase + 5;
  Spawn(id, 1.0f);
  SendStates({At(id, 2.0f)}, 1234);  // format 1, announced by Joined, no decoder
  EXPECT_EQ(client_.state_payloads_refused(), 1u);
  EXPECT_EQ(client_.FindEntity(id)->state.position.x, 1.0f);  // the spawn's, untouched
  SendPayload(Bytes{2, 1, 2, 3});  // format 2 in a room that announced 1
  SendPayload(Bytes{3, 0, 0, 0, 0, 0, 0});         // an emulation's id
  EXPECT_EQ(client_.state_payloads_refused(), 3u);
  EXPECT_TRUE(listener_.updated.empty());
  EXPECT_EQ(client_.state(), ClientState::kConnected);
}

// ClientConfig::decode_states = false (load generators): the state packets are acknowledged
// exactly as by a decoding client, but nothing is decoded or reported; reliable messages are.
class ClientNoDecodeTest : public ClientReceiveTest {
 protected:
  ClientNoDecodeTest() : ClientReceiveTest(Config()) {}
  static ClientConfig Config() {
    ClientConfig config = WithFormat1({});
    config.decode_states = false;
    return config;
  }
};

TEST_F(ClientNoDecodeTest, StatesAreAcknowledgedButNeitherDecodedNorReported) {
  const uint32_t id = kOtherBase + 5;
  Spawn(id, 1.0f);
  ASSERT_EQ(listener_.spawned, std::vector<uint32_t>{id});  // reliable: handled as usual
  const uint64_t bytes = client_.state_bytes_received();
  SendStates({At(id, 2.0f)}, 1234);
  EXPECT_TRUE(relay_handler_.Acked(last_sequence_));
  EXPECT_GT(client_.state_bytes_received(), bytes);
  EXPECT_TRUE(listener_.updated.empty());
  const RemoteEntity* e = client_.FindEntity(id);
  ASSERT_NE(e, nullptr);
  EXPECT_FALSE(e->has_state);
  EXPECT_EQ(e->state.position.x, 1.0f);  // still the spawn's transform
  // Not decoded, so garbage passes the same way: acknowledged (the connection delivered it),
  // counted in bytes, no entity made up from it.
  SendPayload(Bytes{0xEE, 0x01, 0x02, 0x03});
  EXPECT_TRUE(relay_handler_.Acked(last_sequence_));
  EXPECT_EQ(client_.entities().size(), 1u);
  EXPECT_TRUE(listener_.updated.empty());
  // A later despawn (reliable) still applies.
  Despawn(id);
  EXPECT_EQ(listener_.despawned, std::vector<uint32_t>{id});
  EXPECT_EQ(client_.FindEntity(id), nullptr);
}

TEST_F(ClientReceiveTest, StateBeforeSpawnIsKeptSilentlyAndSurvivesTheSpawn) {
  const uint32_t id = kOtherBase + 6;
  SendStates({At(id, 3.0f)}, 50);
  const RemoteEntity* e = client_.FindEntity(id);
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->id, id);
  EXPECT_FALSE(e->spawned);
  EXPECT_TRUE(e->has_state);
  EXPECT_TRUE(listener_.updated.empty());  // no update before the spawn

  Spawn(id, 9.0f);
  e = client_.FindEntity(id);
  ASSERT_NE(e, nullptr);
  EXPECT_TRUE(e->spawned);
  EXPECT_EQ(e->state.position.x, 3.0f);  // the newer state is not overwritten by the spawn
  SendStates({At(id, 4.0f)}, 60);
  EXPECT_EQ(listener_.updated, std::vector<uint32_t>{id});
}

TEST_F(ClientReceiveTest, OwnEntitiesAreNotListedButOthersInOurBlockAre) {
  ASSERT_EQ(client_.state(), ClientState::kConnected);
  Result<uint32_t> own = client_.Spawn({.position = {0, 1, 0}});
  ASSERT_TRUE(own.ok());
  ASSERT_GE(*own, kOwnBase);
  ASSERT_LT(*own, kOwnBase + kEntityIdBlock);
  // A PhyS-owned (offloaded) entity has an id from our block but is not ours to publish.
  const uint32_t offloaded = kOwnBase + 500;
  Spawn(offloaded);
  const uint32_t other = kOtherBase + 1;
  Spawn(other);
  listener_.updated.clear();

  SendStates({At(*own, 5.0f), At(offloaded, 6.0f), At(other, 7.0f)});
  EXPECT_EQ(client_.FindEntity(*own), nullptr);
  ASSERT_NE(client_.FindEntity(offloaded), nullptr);
  EXPECT_EQ(client_.FindEntity(offloaded)->state.position.x, 6.0f);
  ASSERT_NE(client_.FindEntity(other), nullptr);
  EXPECT_EQ(client_.FindEntity(other)->state.position.x, 7.0f);
  EXPECT_EQ(listener_.updated, (std::vector<uint32_t>{offloaded, other}));

  // Once despawned it is no longer ours: a state for it then counts as a remote one.
  ASSERT_TRUE(client_.Despawn(*own).ok());
  SendStates({At(*own, 8.0f)});
  ASSERT_NE(client_.FindEntity(*own), nullptr);
  EXPECT_FALSE(client_.FindEntity(*own)->spawned);
}

TEST_F(ClientReceiveTest, LateStatesOfADespawnedEntityAreIgnoredUntilItRespawns) {
  const uint32_t id = kOtherBase + 9;
  Spawn(id);
  SendStates({At(id, 1.0f)});
  Despawn(id);
  EXPECT_EQ(listener_.despawned, std::vector<uint32_t>{id});
  EXPECT_EQ(client_.FindEntity(id), nullptr);
  listener_.updated.clear();

  SendStates({At(id, 2.0f)});  // late, reordered: must not resurrect it
  EXPECT_EQ(client_.FindEntity(id), nullptr);
  EXPECT_TRUE(client_.entities().empty());
  EXPECT_TRUE(listener_.updated.empty());

  Spawn(id, 3.0f);  // the id is reused
  SendStates({At(id, 4.0f)});
  ASSERT_NE(client_.FindEntity(id), nullptr);
  EXPECT_EQ(client_.FindEntity(id)->state.position.x, 4.0f);
  EXPECT_EQ(listener_.updated, std::vector<uint32_t>{id});
}

TEST_F(ClientReceiveTest, InvalidStatesAreSkippedAndTheRestOfTheBatchApplies) {
  const uint32_t a = kOtherBase + 1, b = kOtherBase + 2, c = kOtherBase + 3;
  Spawn(a);
  Spawn(b);
  listener_.updated.clear();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EntityState bad = At(a, nan);
  EntityState not_unit = At(c, 0.0f);
  not_unit.rotation = {0, 0, 0, 2};
  SendStates({bad, At(b, 1.5f), not_unit});
  ASSERT_NE(client_.FindEntity(a), nullptr);
  EXPECT_FALSE(client_.FindEntity(a)->has_state);
  EXPECT_EQ(client_.FindEntity(c), nullptr);  // an invalid state does not create an entity
  ASSERT_NE(client_.FindEntity(b), nullptr);
  EXPECT_EQ(client_.FindEntity(b)->state.position.x, 1.5f);
  EXPECT_EQ(listener_.updated, std::vector<uint32_t>{b});
}

TEST_F(ClientReceiveTest, ManyEntitiesEachKeepTheirLatestState) {
  std::vector<EntityState> batch;
  for (uint32_t i = 0; i < 30; ++i) {
    Spawn(kOtherBase + i);
    batch.push_back(At(kOtherBase + i, static_cast<float>(i)));
  }
  listener_.updated.clear();
  for (int round = 1; round <= 3; ++round) {
    for (EntityState& s : batch) s.position.y = static_cast<float>(round);
    SendStates(batch, static_cast<uint32_t>(round * 33));
  }
  EXPECT_EQ(listener_.updated.size(), 90u);
  ASSERT_EQ(client_.entities().size(), 30u);
  for (const auto& [id, e] : client_.entities()) {
    EXPECT_EQ(e.id, id);
    EXPECT_EQ(e.state.position.x, static_cast<float>(id - kOtherBase));
    EXPECT_EQ(e.state.position.y, 3.0f);
    EXPECT_EQ(e.state_time_ms, 99u);
  }
}

TEST_F(ClientReceiveTest, ArrivalTimesAreNotRecordedByDefault) {
  const uint32_t id = kOtherBase + 5;
  Spawn(id);
  SendStates({At(id, 2.0f)});
  ASSERT_NE(client_.FindEntity(id), nullptr);
  EXPECT_EQ(client_.FindEntity(id)->arrival_unix_s, 0.0);
  EXPECT_EQ(listener_.last_arrival_unix_s, 0.0);
  EXPECT_EQ(client_.packet_arrival_unix_s(), 0.0);
  EXPECT_EQ(client_.arrival_time_fallbacks(), 0u);
  EXPECT_FALSE(socket_.arrival_times_requested);
}

// Control messages the SDK does not handle (Worker*) reach only a ControlMessageListener set
// through client_testing.h, in order; without one they are dropped and the client carries on.
class RecordingControlListener final : public ControlMessageListener {
 public:
  void OnOtherMessage(const schema::ControlMessage& message) override {
    rooms.push_back(message.body_type() == schema::Body::WorkerUnassign
                        ? message.body_as_WorkerUnassign()->room()
                        : 0);
  }
  std::vector<uint32_t> rooms;
};

TEST_F(ClientReceiveTest, UnhandledControlMessagesGoOnlyToTheInternalHook) {
  auto unassign = [&](uint32_t room) {
    flatbuffers::FlatBufferBuilder fbb(32);
    FinishControl(fbb, schema::CreateWorkerUnassign(fbb, room));
    SendReliable(fbb);
    Pump();
  };
  unassign(7);  // no hook: dropped
  RecordingControlListener hook;
  ClientTesting::SetControlMessageListener(client_, &hook);
  unassign(8);
  unassign(9);
  Spawn(kOtherBase + 1);  // handled by the SDK, not passed on
  EXPECT_EQ(hook.rooms, (std::vector<uint32_t>{8, 9}));
  EXPECT_EQ(listener_.spawned, std::vector<uint32_t>{kOtherBase + 1});
  ClientTesting::SetControlMessageListener(client_, nullptr);
  unassign(10);
  EXPECT_EQ(hook.rooms, (std::vector<uint32_t>{8, 9}));
  EXPECT_EQ(client_.state(), ClientState::kConnected);
}

// The same scripted relay, with ClientConfig::record_arrival_times and a socket answering
// arrival times as `kStamps` says.
template <FakeSocket::Stamps kStamps>
class ClientArrivalTest : public ClientReceiveTest {
 protected:
  ClientArrivalTest() : ClientReceiveTest(Config()) { socket_.SetStamps(kStamps); }
  static ClientConfig Config() {
    ClientConfig config = WithFormat1({});
    config.record_arrival_times = true;
    return config;
  }
  // Spawns `id`, then delivers one state of it; the realtime clock just before and after.
  struct Window {
    double before = 0, after = 0;
  };
  Window SpawnAndSendOneState(uint32_t id) {
    Spawn(id);
    Window w;
    w.before = RealtimeNow();
    SendStates({At(id, 2.0f)});
    w.after = RealtimeNow();
    return w;
  }
};
using ClientScriptedArrivalTest = ClientArrivalTest<FakeSocket::Stamps::kScripted>;
using ClientFallbackArrivalTest = ClientArrivalTest<FakeSocket::Stamps::kNone>;
using ClientKernelArrivalTest = ClientArrivalTest<FakeSocket::Stamps::kKernel>;

TEST_F(ClientScriptedArrivalTest, AStateCarriesTheArrivalTimeOfItsDatagram) {
  EXPECT_TRUE(socket_.arrival_times_requested);
  const uint32_t id = kOtherBase + 5;
  socket_.scripted_arrival_unix_s = 1.7e9 + 0.25;
  Spawn(id);
  ASSERT_NE(client_.FindEntity(id), nullptr);
  EXPECT_EQ(client_.FindEntity(id)->arrival_unix_s, 1.7e9 + 0.25);  // the spawn's, for now

  socket_.scripted_arrival_unix_s = 1.7e9 + 0.5;
  SendStates({At(id, 2.0f)});
  EXPECT_EQ(listener_.updated, std::vector<uint32_t>{id});
  EXPECT_EQ(listener_.last_arrival_unix_s, 1.7e9 + 0.5);  // visible to the callback
  EXPECT_EQ(client_.FindEntity(id)->arrival_unix_s, 1.7e9 + 0.5);
  EXPECT_EQ(client_.packet_arrival_unix_s(), 1.7e9 + 0.5);
  EXPECT_EQ(client_.arrival_time_fallbacks(), 0u);

  // A later datagram without this entity's state leaves its arrival time alone.
  socket_.scripted_arrival_unix_s = 1.7e9 + 0.75;
  Spawn(kOtherBase + 6);
  EXPECT_EQ(client_.FindEntity(id)->arrival_unix_s, 1.7e9 + 0.5);
  EXPECT_EQ(client_.packet_arrival_unix_s(), 1.7e9 + 0.75);
}

TEST_F(ClientFallbackArrivalTest, WithoutSocketSupportTheReadTimeIsUsedAndCounted) {
  EXPECT_TRUE(socket_.arrival_times_requested);
  EXPECT_GT(client_.arrival_time_fallbacks(), 0u);  // the handshake and Joined already
  const uint64_t fallbacks = client_.arrival_time_fallbacks();
  const uint32_t id = kOtherBase + 5;
  const Window w = SpawnAndSendOneState(id);
  ASSERT_EQ(listener_.updated, std::vector<uint32_t>{id});
  EXPECT_GE(listener_.last_arrival_unix_s, w.before);
  EXPECT_LE(listener_.last_arrival_unix_s, listener_.last_update_read_unix_s);
  EXPECT_LE(client_.FindEntity(id)->arrival_unix_s, w.after);
  EXPECT_GT(client_.arrival_time_fallbacks(), fallbacks);
}

TEST_F(ClientKernelArrivalTest, AStateOverLoopbackUdpCarriesTheKernelArrivalTime) {
  EXPECT_TRUE(socket_.arrival_times_requested);
  const uint32_t id = kOtherBase + 5;
  const Window w = SpawnAndSendOneState(id);
  ASSERT_EQ(listener_.updated, std::vector<uint32_t>{id});
  const RemoteEntity* e = client_.FindEntity(id);
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->state.position.x, 2.0f);
  // Stamped by the kernel after the relay's send and before the client read it.
  EXPECT_GE(e->arrival_unix_s, w.before);
  EXPECT_LE(e->arrival_unix_s, listener_.last_update_read_unix_s);
  EXPECT_LE(listener_.last_update_read_unix_s, w.after);
  EXPECT_EQ(listener_.last_arrival_unix_s, e->arrival_unix_s);
  EXPECT_EQ(client_.arrival_time_fallbacks(), 0u);  // every datagram had a kernel timestamp
}

}  // namespace
}  // namespace edgephys
