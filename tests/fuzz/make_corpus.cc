// Writes the seed corpus of the fuzz targets: make_corpus <dir> creates <dir>/<target>/<seed>
// for packet_fuzz, reliable_fuzz, state_fuzz and message_fuzz (input formats: see each
// target's header comment). Small valid inputs, so the fuzzers start past the verifiers.
// The committed corpus (tests/fuzz/corpus) was produced by this program.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "client/client.h"
#include "physics_backend/worker_protocol.h"
#include "protocol/app_message_codec.h"
#include "protocol/byte_io.h"
#include "protocol/container_builder.h"
#include "protocol/delta_codec.h"
#include "loadgen/emulation/emulation_codec.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/packet_seal.h"
#include "protocol/property_codec.h"
#include "protocol/quantize.h"
#include "protocol/soft_body_codec.h"
#include "protocol/soft_delta_stream.h"
#include "tests/fuzz/fuzz_world.h"

namespace edgephys::fuzz {
namespace {

using Bytes = std::vector<uint8_t>;
namespace fs = std::filesystem;

fs::path g_root;

void Write(const std::string& target, const std::string& name, const Bytes& data) {
  fs::create_directories(g_root / target);
  std::ofstream f(g_root / target / name, std::ios::binary);
  f.write(reinterpret_cast<const char*>(data.data()), static_cast<std::streamsize>(data.size()));
}

// Builds a record input: mode byte then records.
struct Input {
  Bytes bytes;
  explicit Input(uint8_t mode) { bytes.push_back(mode); }
  Input& Add(uint8_t tag, const Bytes& b) {
    PutRecord(&bytes, tag, b);
    return *this;
  }
};

Bytes Finish(flatbuffers::FlatBufferBuilder& fbb) {
  return Bytes(fbb.GetBufferPointer(), fbb.GetBufferPointer() + fbb.GetSize());
}

template <typename F>
Bytes Msg(F&& build) {
  flatbuffers::FlatBufferBuilder fbb(256);
  FinishControl(fbb, build(fbb));
  return Finish(fbb);
}

// Connection header (after the prefix) and chunks.
Bytes Header(uint16_t seq, uint16_t ack, uint32_t ack_bits) {
  Bytes b(8);
  StoreU16LE(b.data(), seq);
  StoreU16LE(b.data() + 2, ack);
  StoreU32LE(b.data() + 4, ack_bits);
  return b;
}
void ReliableChunk(Bytes* b, uint16_t id, bool last, const Bytes& data) {
  size_t at = b->size();
  b->resize(at + 6);
  (*b)[at] = 0x01;
  StoreU16LE(b->data() + at + 1, id);
  (*b)[at + 3] = last ? 1 : 0;
  StoreU16LE(b->data() + at + 4, static_cast<uint16_t>(data.size()));
  b->insert(b->end(), data.begin(), data.end());
}
void UnreliableChunk(Bytes* b, const Bytes& data) {
  size_t at = b->size();
  b->resize(at + 3);
  (*b)[at] = 0x02;
  StoreU16LE(b->data() + at + 1, static_cast<uint16_t>(data.size()));
  b->insert(b->end(), data.begin(), data.end());
}

Bytes FloatStates(std::initializer_list<EntityState> states) {
  Bytes out(kMaxUnreliablePayload);
  FloatStateEncoder enc;
  enc.Begin(out, 1234);
  for (const auto& s : states) enc.Add(s);
  out.resize(enc.Finish());
  return out;
}

EntityState St(uint32_t id, float x, float y, float z) { return {id, {x, y, z}, {0, 0, 0, 1}}; }

Bytes SpawnMsg(const EntitySpec& spec) {
  return Msg([&](auto& fbb) { return schema::CreateSpawn(fbb, AddContainer(fbb, spec)); });
}

constexpr uint32_t kOffloaded = static_cast<uint32_t>(schema::EntityFlags::Offloaded);
constexpr uint32_t kInteractable = static_cast<uint32_t>(schema::EntityFlags::Interactable);
constexpr uint32_t kHand = static_cast<uint32_t>(schema::EntityFlags::Hand);

// Entities of player `owner` in id block `slot`.
EntitySpec Ground(uint32_t slot, uint32_t owner) {
  EntitySpec s = StaticBox(slot * kEntityIdBlock + 1, {0, -0.5f, 0}, {10, 0.5f, 10});
  s.owner = owner;
  s.flags = kOffloaded;
  return s;
}
EntitySpec Cube(uint32_t slot, uint32_t owner) {
  EntitySpec s = DynamicBox(slot * kEntityIdBlock + 2, {0, 0.3f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  s.owner = owner;
  s.flags = kOffloaded | kInteractable;
  s.name = "cube";
  return s;
}
EntitySpec HandSpec(uint32_t slot, uint32_t owner) {
  EntitySpec s = TriggerHand(slot * kEntityIdBlock + 3, {0, 0.3f, 0}, 0.3f);
  s.owner = owner;
  s.flags = kOffloaded | kHand;
  return s;
}
EntitySpec Plain(uint32_t slot, uint32_t owner) {
  EntitySpec s;
  s.id = slot * kEntityIdBlock + 4;
  s.owner = owner;
  s.position = {1, 2, 3};
  s.name = "plain";
  return s;
}
EntitySpec Soft(uint32_t slot, uint32_t owner) {
  EntitySpec s;
  s.id = slot * kEntityIdBlock + 5;
  s.owner = owner;
  s.flags = kOffloaded;
  s.position = {0, 1, 0};
  SoftBodySpec soft;
  soft.particles = {0, 1, 0, 0.1f, 1, 0, 0, 1.1f, 0, 0, 1, 0.1f};
  soft.masses = {0.1f, 0.1f, 0.1f, 0.1f};
  soft.springs = {0, 1, 0, 2, 0, 3, 1, 2, 1, 3, 2, 3};
  soft.stiffness = 50;
  soft.damping = 0.1f;
  s.soft_body = soft;
  return s;
}
EntitySpec Jointed(uint32_t slot, uint32_t owner) {
  EntitySpec s = DynamicSphere(slot * kEntityIdBlock + 6, {0.5f, 1, 0}, 0.1f, 0.5f);
  s.owner = owner;
  s.flags = kOffloaded;
  JointSpec j;
  j.kind = schema::JointKind::Fixed;
  j.connected_entity = slot * kEntityIdBlock + 2;
  s.joints.push_back(j);
  return s;
}

Bytes JoinRoom(const char* room) {
  return Msg([&](auto& fbb) { return schema::CreateJoinRoom(fbb, fbb.CreateString(room)); });
}

Bytes WorkerResult(uint32_t room) {
  return Msg([&](auto& fbb) {
    std::vector<flatbuffers::Offset<schema::PhysicsEvent>> events{
        schema::CreatePhysicsEvent(fbb, schema::PhysicsEventKind::CollisionEnter, 65538, 65537)};
    std::vector<flatbuffers::Offset<schema::WorkerGrabResult>> grabs{
        schema::CreateWorkerGrabResult(fbb, 65538, 65539, true, fbb.CreateString("ok"))};
    return schema::CreateWorkerResult(fbb, room, fbb.CreateVector(events), fbb.CreateVector(grabs));
  });
}

Bytes WorkerStates(uint32_t room) {
  std::vector<RoomPhysics::MovedBody> bodies(2);
  bodies[0].state = St(65538, 0, 0.3f, 0);
  bodies[1].state = St(65542, 0.5f, 1, 0);
  bodies[1].linear = {0, -1, 0};
  Bytes out(kMaxUnreliablePayload);
  size_t n = 0;
  out.resize(EncodeWorkerStates(room, bodies, 0, out, &n));
  return out;
}

Bytes WorkerSoft(uint32_t room) {
  std::vector<Vec3f> nodes{{0, 1, 0}, {0.1f, 1, 0}, {0, 1.1f, 0}, {0, 1, 0.1f}};
  Bytes out(kMaxUnreliablePayload);
  uint32_t n = 0;
  out.resize(EncodeWorkerSoftChunk(room, 65541, nodes, 0, out, &n));
  return out;
}

Bytes SoftChunk(uint32_t id) {
  std::vector<Vec3f> nodes{{0, 1, 0}, {0.1f, 1, 0}, {0, 1.1f, 0}, {0, 1, 0.1f}};
  Bytes out(kMaxUnreliablePayload);
  uint32_t n = 0;
  out.resize(EncodeSoftBodyChunk(77, id, nodes, 0, 0.001f, out, &n));
  return out;
}

// Two format-11 payloads: a keyframe, then a delta against it.
std::vector<Bytes> SoftDeltaPayloads(uint32_t id) {
  SoftDeltaSender sender({0.001f, 0.0f});
  std::vector<Vec3f> nodes{{0, 1, 0}, {0.1f, 1, 0}, {0, 1.1f, 0}, {0, 1, 0.1f}};
  std::vector<Bytes> out;
  for (uint32_t v = 1; v <= 2; ++v) {
    Bytes buf(kMaxUnreliablePayload);
    if (!sender.Prepare(id, v, nodes, 100 * v, v, 0.1)) break;
    sender.BeginPayload(buf, 100 * v);
    uint32_t first = 0;
    (void)sender.AddRecords(id, &first);
    buf.resize(sender.FinishPayload());
    sender.OnSent(static_cast<uint16_t>(v), v);
    (void)sender.OnAcked(static_cast<uint16_t>(v));
    out.push_back(buf);
    for (Vec3f& n : nodes) n.y += 0.004f;
  }
  return out;
}

// Three format-2 payloads: a keyframe, then deltas against acknowledged states.
std::vector<Bytes> DeltaPayloads() {
  auto params = *MakeQuantizationParams(QuantizationConfig{});
  DeltaEncoder enc(params);
  std::vector<Bytes> out;
  for (int p = 0; p < 3; ++p) {
    Bytes buf(kMaxUnreliablePayload);
    enc.Begin(buf, static_cast<uint32_t>(1000 + 33 * p));
    for (uint32_t id : {65537u, 65538u, 131073u}) {
      enc.Add(St(id, 0.01f * static_cast<float>(p) + static_cast<float>(id % 7), 1.0f, -2.0f));
    }
    buf.resize(enc.Finish());
    enc.OnSent(static_cast<uint16_t>(p), p * 0.033);
    enc.OnPacketAcked(static_cast<uint16_t>(p));
    out.push_back(buf);
  }
  return out;
}

Bytes Photon() {
  Bytes out(kMaxUnreliablePayload);
  PhotonEmulationEncoder enc;
  enc.Begin(out, 99);
  enc.Add(St(65537, 1, 2, 3));
  enc.Add(St(65538, 4, 5, 6));
  out.resize(enc.Finish());
  return out;
}

Bytes Paper() {
  Bytes out(kMaxUnreliablePayload);
  PaperEmulationEncoder enc;
  enc.Begin(out, 99);
  enc.AddFields(St(65537, 1, 2, 3), kFieldPosition);
  enc.AddFields(St(65538, 4, 5, 6), kFieldRotation);
  enc.Add(St(65539, 7, 8, 9));
  out.resize(enc.Finish());
  return out;
}

// A client token (relay part | session secret) with a fixed secret: the same bytes each run.
Bytes Token() {
  JoinToken t;
  t.room = kFuzzRoom;
  t.player_id = 5;
  t.expiry_unix_s = kUnixNow + 600;
  t.nonce = 42;
  t.session_secret.fill(0x5e);
  return *SignJoinToken(t, kFuzzSecret);
}

Bytes RelayPart() {
  const Bytes client = Token();
  auto relay = SplitClientToken(client)->relay_token;
  return Bytes(relay.begin(), relay.end());
}

void PacketCorpus() {
  // A Hello from a stranger (a Challenge comes back), and a bad Connect.
  Bytes hello_packet = [] {
    flatbuffers::FlatBufferBuilder fbb(64);
    FinishControl(fbb, schema::CreateHello(fbb, 12345));
    return BuildHandshakePacket(PacketType::kHello, fbb, kMinHelloPacketSize);
  }();
  Write("packet_fuzz", "hello", Input(0).Add(0, hello_packet).bytes);
  // A Connect of handshake version 2 (relay part, client key, version, proof; its cookie is
  // not the relay's), and one of the older layout (whole token, no version, no proof).
  const Bytes client_key(kKeyExchangePublicSize, 0x4b);
  Bytes connect_packet = [&] {
    const uint8_t cookie[kCookieSize] = {};
    const Bytes token = RelayPart();
    return BuildConnectPacket({12345, cookie, token, client_key}, SplitClientToken(Token())->session_secret);
  }();
  Write("packet_fuzz", "connect", Input(0).Add(0, connect_packet).bytes);
  Bytes old_connect_packet = [] {
    flatbuffers::FlatBufferBuilder fbb(256);
    uint8_t cookie[kCookieSize] = {};
    Bytes token = RelayPart();
    FinishControl(fbb, schema::CreateConnect(fbb, fbb.CreateVector(cookie, kCookieSize),
                                             fbb.CreateVector(token), 12345));
    return BuildHandshakePacket(PacketType::kConnect, fbb);
  }();
  Write("packet_fuzz", "connect_v1", Input(0).Add(0, old_connect_packet).bytes);

  // Session traffic from A (unit 0 was its JoinRoom): a reliable Spawn and a state.
  Bytes data = Header(40, 0, 0);
  ReliableChunk(&data, 1, true, SpawnMsg(Plain(1, 1)));
  UnreliableChunk(&data, FloatStates({St(65540, 1, 2, 3)}));
  Bytes fragmented = Header(41, 0, 0);
  Bytes big = SpawnMsg(Ground(1, 1));
  Bytes first(big.begin(), big.begin() + static_cast<long>(big.size() / 2));
  Bytes second(big.begin() + static_cast<long>(big.size() / 2), big.end());
  ReliableChunk(&fragmented, 2, false, first);
  ReliableChunk(&fragmented, 3, true, second);
  Bytes disconnect = Header(42, 0, 0);
  disconnect.push_back(2);  // kClientLeft
  Write("packet_fuzz", "session", Input(1).Add(2, data).Add(2, fragmented).Add(2 | 8, disconnect).bytes);
  // The raw form too (prefix included, connection id unknown here).
  Bytes raw(kPacketPrefixSize);
  WritePacketPrefix(PacketType::kData, 1, raw);
  raw.insert(raw.end(), data.begin(), data.end());
  Write("packet_fuzz", "session_raw", Input(1).Add(1, raw).bytes);

  // To client A (relay sent Joined and RoomState as units 0 and 1).
  Bytes to_client = Header(30, 0, 0);
  ReliableChunk(&to_client, 2, true, SpawnMsg(Plain(2, 2)));
  UnreliableChunk(&to_client, DeltaPayloads()[0]);
  Write("packet_fuzz", "to_client", Input(1).Add(3 | 8, to_client).bytes);

  // To the handshaking client B: a Challenge then an Accept, then a Reject.
  Bytes challenge = Msg([](auto& fbb) {
    uint8_t cookie[kCookieSize] = {9};
    return schema::CreateChallenge(fbb, fbb.CreateVector(cookie, kCookieSize));
  });
  Bytes accept = Msg([](auto& fbb) { return schema::CreateAccept(fbb, 77, 2, 100, 5000); });
  // An Accept with a relay key and a proof (the proof cannot match: B's key is random).
  Bytes proved_accept = Msg([](auto& fbb) {
    const Bytes relay_key(kKeyExchangePublicSize, 0x52);
    const HandshakeProof proof = AcceptProof(SessionSecret{}, {{}, relay_key, 77, 2, 100, 5000});
    return schema::CreateAccept(fbb, 77, 2, 100, 5000, fbb.CreateVector(relay_key),
                                fbb.CreateVector(proof.data(), proof.size()));
  });
  Bytes reject = Msg([](auto& fbb) { return schema::CreateReject(fbb, schema::RejectReason::BadToken); });
  Write("packet_fuzz", "handshake_client",
        Input(0).Add(4 | 8 | (2 << 4), challenge).Add(4 | 8 | (4 << 4), accept).bytes);
  Write("packet_fuzz", "reject_client", Input(0).Add(4 | 8 | (5 << 4), reject).bytes);
  Write("packet_fuzz", "proved_accept_client",
        Input(0).Add(4 | 8 | (2 << 4), challenge).Add(4 | 8 | (4 << 4), proved_accept).bytes);
}

void ReliableCorpus() {
  Bytes msg(300, 0xab);
  Bytes one = Header(0, 0xffff, 0);
  ReliableChunk(&one, 0, true, msg);
  Bytes frag1 = Header(1, 0xffff, 0);
  ReliableChunk(&frag1, 1, false, Bytes(1000, 1));
  Bytes frag2 = Header(3, 0xffff, 0);
  ReliableChunk(&frag2, 3, true, Bytes(10, 3));
  Bytes frag3 = Header(2, 0xffff, 0);
  ReliableChunk(&frag3, 2, false, Bytes(1000, 2));
  UnreliableChunk(&frag3, Bytes(20, 7));
  Bytes ack = Header(4, 0, 0x3);
  Bytes disconnect = Header(5, 0, 0);
  disconnect.push_back(5);
  Write("reliable_fuzz", "raw_reassembly",
        Input(0).Add(1, Bytes(800, 9)).Add(3, {10}).Add(0, one).Add(0, frag1).Add(0, frag2)
            .Add(0, frag3).Add(0, ack).Add(3, {200}).bytes);
  Write("reliable_fuzz", "raw_disconnect", Input(0).Add(0, one).Add(4, disconnect).bytes);
  // Reassembly bound (max_held_reliable_bytes): 30 units in order, 30 beyond a gap (some
  // refused unacknowledged), then the gap filled in order.
  Input held(0);
  uint16_t seq = 0;
  auto unit = [&](uint16_t id) {
    Bytes p = Header(seq++, 0xffff, 0);
    ReliableChunk(&p, id, false, Bytes(1024, static_cast<uint8_t>(id)));
    held.Add(0, p);
  };
  for (uint16_t id = 0; id < 30; ++id) unit(id);
  for (uint16_t id = 89; id >= 60; --id) unit(id);
  for (uint16_t id = 30; id < 60; ++id) unit(id);
  Write("reliable_fuzz", "raw_held_bound", held.bytes);
  Bytes unreliable = Header(0, 0xffff, 0);
  UnreliableChunk(&unreliable, Bytes(100, 5));
  Bytes older = Header(7, 0xffff, 0);
  UnreliableChunk(&older, Bytes(10, 6));
  Write("reliable_fuzz", "raw_unreliable",
        Input(0).Add(0, older).Add(0, unreliable).Add(2, Bytes(50, 1)).Add(3, {5}).bytes);
  // Pair: messages of 1 byte to several units, some unreliable, link noise from the records.
  Write("reliable_fuzz", "pair",
        Input(1).Add(0x10, {1, 2, 3}).Add(0x22, Bytes(100, 4)).Add(0x31, Bytes(40, 5))
            .Add(0x02, Bytes(3000, 6)).Add(0x50, {0, 1, 2, 3, 0, 0, 2, 1}).bytes);
}

void StateCorpus() {
  Input all(0);
  all.Add(0, FloatStates({St(1, 1, 2, 3), St(2, 4, 5, 6)}));
  for (const Bytes& p : DeltaPayloads()) all.Add(1, p);
  all.Add(2, Photon()).Add(2 | 8, Paper()).Add(3 | 8, SoftChunk(65541));
  all.Add(4, WorkerStates(1)).Add(5, WorkerSoft(1));
  for (const Bytes& p : SoftDeltaPayloads(65541)) all.Add(17, p);  // 17 % 7 == 3, bit 4: format 11
  Write("state_fuzz", "all_formats", all.bytes);
  Input delta(0);
  for (const Bytes& p : DeltaPayloads()) delta.Add(1, p);
  Write("state_fuzz", "delta", delta.bytes);
  // The client token, its relay part, and the client token's printable form.
  Bytes token = Token();
  std::string text = Base64UrlEncode(token);
  Write("state_fuzz", "token",
        Input(0).Add(6, token).Add(6, RelayPart()).Add(6, Bytes(text.begin(), text.end())).bytes);
  // Custom quantisation (mode bit 0): bounds, step, rotation bound as raw floats.
  Input custom(1);
  for (float f : {-50.f, -10.f, -50.f, 50.f, 40.f, 50.f, 0.0005f, 0.5f}) {
    uint8_t b[4];
    StoreF32LE(b, f);
    custom.bytes.insert(custom.bytes.end(), b, b + 4);
  }
  custom.Add(1, DeltaPayloads()[0]);
  Write("state_fuzz", "custom_quantization", custom.bytes);
}

void MessageCorpus() {
  // Relay, embedded PhyS: A is player 1 in slot 1, C player 2 in slot 2.
  Bytes despawn = Msg([](auto& fbb) { return schema::CreateDespawn(fbb, 65537); });
  Bytes grab = Msg([](auto& fbb) { return schema::CreateGrab(fbb, 65538, 65539); });
  Bytes release = Msg([](auto& fbb) { return schema::CreateRelease(fbb, 65538); });
  Bytes leave = Msg([](auto& fbb) { return schema::CreateLeaveRoom(fbb); });
  Bytes worker_hello = Msg([](auto& fbb) { return schema::CreateWorkerHello(fbb, 4); });
  Write("message_fuzz", "relay_physics",
        Input(0).Add(0, SpawnMsg(Ground(1, 1))).Add(0, SpawnMsg(Cube(1, 1)))
            .Add(0, SpawnMsg(HandSpec(1, 1))).Add(3, {10}).Add(0, grab).Add(3, {5})
            .Add(0, release).Add(2, FloatStates({St(65539, 0, 0.4f, 0)})).Add(0, despawn).bytes);
  // Grabs carrying the hand's pose: near (applied), far (refused), NaN, naming another entity.
  auto grab_at = [](float x, float y, uint32_t pose_entity) {
    return Msg([&](auto& fbb) {
      const schema::Pose pose(pose_entity, schema::Vec3(x, y, 0), schema::Quat(0, 0, 0, 1));
      return schema::CreateGrab(fbb, 65538, 65539, &pose);
    });
  };
  Write("message_fuzz", "relay_grab_pose",
        Input(0).Add(0, SpawnMsg(Ground(1, 1))).Add(0, SpawnMsg(Cube(1, 1)))
            .Add(0, SpawnMsg(HandSpec(1, 1))).Add(3, {10}).Add(0, grab_at(0, 0.4f, 65539))
            .Add(3, {5}).Add(0, release).Add(0, grab_at(9, 0.4f, 65539))
            .Add(0, grab_at(std::nanf(""), 0.4f, 65539)).Add(0, grab_at(0, 0.4f, 65538))
            .Add(3, {5}).bytes);
  Write("message_fuzz", "relay_soft_joint",
        Input(0).Add(0, SpawnMsg(Cube(1, 1))).Add(0, SpawnMsg(Jointed(1, 1)))
            .Add(0, SpawnMsg(Soft(1, 1))).Add(3, {15}).Add(1, SpawnMsg(Plain(2, 2))).bytes);
  Write("message_fuzz", "relay_misc",
        Input(0).Add(0, SpawnMsg(Plain(1, 1))).Add(1, JoinRoom("other")).Add(1, leave)
            .Add(1, JoinRoom(kFuzzRoom)).Add(0, worker_hello).Add(0, WorkerResult(1))
            .Add(1, despawn).Add(2, FloatStates({St(65540, 5, 5, 5), St(131073, 1, 1, 1)})).bytes);

  // Application messages (docs/protocol.md §4a): to the room, the others, player 2, a player
  // not in the room, an unknown target, an empty and a 1 KiB payload; from A and from C.
  auto app = [](schema::MessageTarget target, uint32_t to, size_t size) {
    return Msg([&](auto& fbb) {
      Bytes payload(size, 0x5a);
      return schema::CreateAppMessage(fbb, target, to, 0, fbb.CreateVector(payload));
    });
  };
  using T = schema::MessageTarget;
  Write("message_fuzz", "relay_app_message",
        Input(0).Add(0, app(T::Room, 0, 5)).Add(1, app(T::Others, 0, 1024))
            .Add(0, app(T::Player, 2, 3)).Add(0, app(T::Player, 99, 1))
            .Add(1, app(static_cast<T>(7), 0, 2)).Add(0, app(T::Room, 0, 0)).Add(3, {4}).bytes);

  // Relay: unreliable messages (format 15, docs/protocol.md §4a) from A: to the room, the
  // others, player 2, a player not in the room, an unknown target, a full datagram, a header
  // cut short, an empty payload.
  auto unreliable = [](uint8_t target, uint32_t to, uint32_t sender, uint32_t seq, size_t size) {
    AppMessageHeader h;
    h.target = target;
    h.to_player = to;
    h.sender = sender;
    h.sequence = seq;
    Bytes payload(size, 0x3c), out(kAppMessageHeaderSize + size);
    out.resize(EncodeAppMessage(h, payload, out));
    return out;
  };
  Write("message_fuzz", "relay_app_message_unreliable",
        Input(0).Add(2, unreliable(0, 0, 0, 0, 5)).Add(2, unreliable(1, 0, 0, 0, 40))
            .Add(2, unreliable(2, 2, 0, 0, 3)).Add(2, unreliable(2, 99, 0, 0, 1))
            .Add(2, unreliable(7, 0, 0, 0, 2))
            .Add(2, unreliable(1, 0, 0, 0, kMaxUnreliableMessagePayload))
            .Add(2, Bytes{kAppMessageFormat, 1, 0}).Add(2, unreliable(0, 0, 5, 9, 0))
            .Add(0, app(T::Room, 0, 5)).Add(3, {4}).bytes);

  // Relay: property writes (docs/protocol.md §4b): set, compare-and-set won and lost, owner-only
  // refused, and malformed (unknown type, NaN, long key, unknown entity).
  auto set = [](uint32_t entity, const std::string& key, PropertyValue v, bool check,
                uint32_t expected, uint8_t authority) {
    return Msg([&](auto& fbb) {
      const auto k = fbb.CreateString(key);
      const auto value = WritePropertyValue(fbb, v);
      return schema::CreatePropertySet(fbb, entity, k, value, check, expected,
                                       static_cast<schema::PropertyAuthority>(authority), 1);
    });
  };
  PropertyValue bad_type = PropertyValue::Int64(1);
  bad_type.type = static_cast<PropertyType>(9);
  Write("message_fuzz", "relay_properties",
        Input(0).Add(0, set(0, "step", PropertyValue::Int64(1), true, 0, 1))
            .Add(1, set(0, "step", PropertyValue::Int64(2), true, 1, 0))
            .Add(0, set(0, "step", PropertyValue::Int64(3), true, 1, 0))
            .Add(0, set(0, "title", PropertyValue::String("suture"), false, 0, 0))
            .Add(1, set(0, "title", PropertyValue::String("mine"), false, 0, 0))
            .Add(0, set(0, "where", PropertyValue::Vec3({1, 2, 3}), false, 0, 1))
            .Add(0, set(0, "aim", PropertyValue::Quat({0, 0, 0, 1}), false, 0, 1))
            .Add(1, set(0, "blob", PropertyValue::Bytes(std::string(300, 'b')), false, 0, 1))
            .Add(0, set(0, "bad", bad_type, false, 0, 0))
            .Add(0, set(0, "nan", PropertyValue::Double(std::nan("")), false, 0, 0))
            .Add(0, set(0, std::string(65, 'k'), PropertyValue::Bool(true), false, 0, 0))
            .Add(0, set(65537, "tip", PropertyValue::Double(1), false, 0, 0)).bytes);

  // Relay: ownership requests (docs/protocol.md §4c): refused while takeover is forbidden,
  // allowed, granted, handed back, handed to a player not in the room, an unknown action, a
  // stale state of the previous owner, a release.
  auto own = [](uint32_t entity, schema::OwnershipAction action, uint32_t to, bool takeover) {
    return Msg([&](auto& fbb) {
      return schema::CreateOwnershipRequest(fbb, entity, action, to, takeover);
    });
  };
  using O = schema::OwnershipAction;
  Write("message_fuzz", "relay_ownership",
        Input(0).Add(0, SpawnMsg(Plain(1, 1))).Add(1, own(65537, O::Request, 0, false))
            .Add(0, own(65537, O::SetTakeover, 0, true)).Add(1, own(65537, O::Request, 0, false))
            .Add(2, FloatStates({St(65537, 1, 1, 1)})).Add(1, own(65537, O::HandOver, 1, false))
            .Add(0, own(65537, O::HandOver, 99, false)).Add(0, own(65537, static_cast<O>(9), 0, false))
            .Add(0, own(70000, O::Request, 0, false)).Add(0, own(65537, O::Release, 0, false)).bytes);
  // Relay: leave choices (SetOwnerLeave): PhyS, an unknown value, by a non-owner, of an unknown
  // entity; then the owner leaves; and a spawn carrying an unknown choice.
  auto leave_choice = [](uint32_t entity, uint8_t choice) {
    return Msg([&](auto& fbb) {
      return schema::CreateOwnershipRequest(fbb, entity, O::SetOwnerLeave, 0, false, nullptr,
                                            nullptr, static_cast<schema::OwnerLeave>(choice));
    });
  };
  EntitySpec bad_choice = Plain(1, 1);
  bad_choice.id += 1;
  bad_choice.on_owner_leave = 7;
  Write("message_fuzz", "relay_owner_leave",
        Input(0).Add(0, SpawnMsg(Plain(1, 1))).Add(0, leave_choice(65540, 2))
            .Add(0, leave_choice(65540, 9)).Add(1, leave_choice(65540, 3))
            .Add(0, leave_choice(70000, 1)).Add(0, SpawnMsg(bad_choice))
            .Add(0, Msg([](auto& fbb) { return schema::CreateLeaveRoom(fbb); })).bytes);

  // Relay, remote PhyS: room handle 1 is on worker W.
  Write("message_fuzz", "relay_worker",
        Input(1).Add(0, SpawnMsg(Ground(1, 1))).Add(0, SpawnMsg(Cube(1, 1)))
            .Add(0, SpawnMsg(HandSpec(1, 1))).Add(0, SpawnMsg(Soft(1, 1))).Add(2, WorkerStates(1))
            .Add(2, WorkerSoft(1)).Add(1, WorkerResult(1)).Add(0, grab).Add(1, worker_hello)
            .Add(3, FloatStates({St(65539, 0, 0.5f, 0)})).Add(0, despawn).bytes);

  // Client side, after a Joined of each state format.
  Bytes room_state = Msg([](auto& fbb) {
    std::vector<uint32_t> players{7, 8};
    return schema::CreateRoomState(fbb, fbb.CreateString(kFuzzRoom), fbb.CreateVector(players), 2);
  });
  Bytes joined_player = Msg([](auto& fbb) { return schema::CreatePlayerJoined(fbb, 9); });
  Bytes left_player = Msg([](auto& fbb) { return schema::CreatePlayerLeft(fbb, 8); });
  Bytes event = Msg([](auto& fbb) {
    return schema::CreatePhysicsEvent(fbb, schema::PhysicsEventKind::Grabbed, 65537, 65539);
  });
  Bytes error = Msg([](auto& fbb) {
    return schema::CreateError(fbb, schema::RejectReason::NotOwner, 65537, fbb.CreateString("no"));
  });
  Bytes client_despawn = Msg([](auto& fbb) { return schema::CreateDespawn(fbb, 65538); });
  auto client_input = [&](uint8_t format) {
    Input in(static_cast<uint8_t>(2 | 4 | ((format - 1) << 3)));
    in.Add(0, room_state).Add(0, SpawnMsg(Plain(1, 8))).Add(0, SpawnMsg(Cube(1, 8)))
        .Add(0, SpawnMsg(Soft(1, 8)));
    switch (format) {
      case 1: in.Add(1, FloatStates({St(65540, 1, 1, 1), St(65538, 0, 1, 0)})); break;
      case 2:
        for (const Bytes& p : DeltaPayloads()) in.Add(1, p);
        break;
      case 3: in.Add(1, Photon()); break;
      case 4: in.Add(1, Paper()); break;
    }
    in.Add(1, SoftChunk(65541)).Add(0, joined_player).Add(0, left_player).Add(0, event)
        .Add(0, error).Add(0, client_despawn);
    return in.bytes;
  };
  for (uint8_t format = 1; format <= 4; ++format) {
    Write("message_fuzz", "client_format" + std::to_string(format), client_input(format));
  }
  // Client side: application messages (one empty, one of 1 KiB), after a Joined.
  Write("message_fuzz", "client_app_message",
        Input(2 | 4).Add(0, app(T::Others, 0, 2)).Add(0, app(T::Player, 1, 0))
            .Add(0, app(T::Room, 0, 1024)).bytes);
  // Client side: unreliable messages (format 15) from the relay: in order, a duplicate, an older
  // one, another sender, no sender (malformed), a header cut short, a full datagram.
  Write("message_fuzz", "client_app_message_unreliable",
        Input(2 | 4).Add(1, unreliable(1, 0, 7, 1, 4)).Add(1, unreliable(0, 0, 7, 2, 0))
            .Add(1, unreliable(0, 0, 7, 2, 3)).Add(1, unreliable(0, 0, 7, 1, 3))
            .Add(1, unreliable(2, 1, 8, 5, 10)).Add(1, unreliable(0, 0, 0, 3, 1))
            .Add(1, Bytes{kAppMessageFormat, 0, 0, 0, 0})
            .Add(1, unreliable(0, 0, 8, 6, kMaxUnreliableMessagePayload)).bytes);
  // Client side: property announcements and a conflict (and one with a NaN the SDK ignores).
  auto changed = [](uint32_t entity, const std::string& key, PropertyValue v, uint32_t version) {
    return Msg([&](auto& fbb) {
      const auto k = fbb.CreateString(key);
      const auto value = WritePropertyValue(fbb, v);
      return schema::CreatePropertyChanged(fbb, entity, k, value, version, 7, 7,
                                           schema::PropertyAuthority::Anyone, 3);
    });
  };
  Bytes conflict = Msg([](auto& fbb) {
    const auto k = fbb.CreateString("step");
    const auto value = WritePropertyValue(fbb, PropertyValue::Int64(4));
    return schema::CreatePropertyConflict(fbb, 5, 0, k, value, 2, 7);
  });
  Write("message_fuzz", "client_properties",
        Input(2 | 4).Add(0, changed(0, "step", PropertyValue::Int64(4), 2))
            .Add(0, changed(0, "title", PropertyValue::String("suture"), 1))
            .Add(0, changed(65537, "tip", PropertyValue::Vec3({1, 2, 3}), 1))
            .Add(0, changed(0, "nan", PropertyValue::Vec3({std::nanf(""), 0, 0}), 1))
            .Add(0, conflict).bytes);
  // Client side: ownership changes (gained, lost, an older sequence, an unknown entity).
  auto changed_owner = [](uint32_t entity, uint32_t owner, uint32_t seq) {
    return Msg([&](auto& fbb) {
      return schema::CreateOwnershipChanged(fbb, entity, owner, seq, 7, seq % 2 == 0);
    });
  };
  Write("message_fuzz", "client_ownership",
        Input(2 | 4).Add(0, changed_owner(65537, 1, 1)).Add(0, changed_owner(65537, 7, 2))
            .Add(0, changed_owner(65537, 1, 1)).Add(0, changed_owner(99999, 1, 5)).bytes);
  // Client side as a PhyS worker: relay -> worker messages.
  EntitySpec cube = Cube(1, 0);
  Bytes assign = Msg([](auto& fbb) { return schema::CreateWorkerAssign(fbb, 1, 1.0f / 60); });
  Bytes add_ground = Msg([](auto& fbb) {
    return schema::CreateWorkerAdd(fbb, 1, 1, AddContainer(fbb, Ground(1, 0)));
  });
  Bytes add_cube = Msg([&](auto& fbb) { return schema::CreateWorkerAdd(fbb, 1, 2, AddContainer(fbb, cube)); });
  Bytes add_hand = Msg([](auto& fbb) {
    return schema::CreateWorkerAdd(fbb, 1, 1, AddContainer(fbb, HandSpec(1, 0)));
  });
  Bytes drive = Msg([](auto& fbb) {
    schema::Pose pose(65539, schema::Vec3(0, 0.3f, 0), schema::Quat(0, 0, 0, 1));
    std::vector<schema::Pose> poses{pose};
    return schema::CreateWorkerDrive(fbb, 1, fbb.CreateVectorOfStructs(poses));
  });
  Bytes wgrab = Msg([](auto& fbb) { return schema::CreateWorkerGrab(fbb, 1, 65538, 65539, false); });
  Bytes wrelease = Msg([](auto& fbb) { return schema::CreateWorkerRelease(fbb, 1, 65538); });
  Bytes restore = Msg([](auto& fbb) {
    schema::Pose pose(65538, schema::Vec3(0, 1, 0), schema::Quat(0, 0, 0, 1));
    schema::Vec3 lin(0, 1, 0), ang(0, 0, 1);
    return schema::CreateWorkerRestore(fbb, 1, 65538, &pose, &lin, &ang);
  });
  Bytes remove = Msg([](auto& fbb) { return schema::CreateWorkerRemove(fbb, 1, 65537); });
  Bytes unassign = Msg([](auto& fbb) { return schema::CreateWorkerUnassign(fbb, 1); });
  Write("message_fuzz", "client_worker",
        Input(2).Add(0, assign).Add(0, add_ground).Add(0, add_cube).Add(0, add_hand)
            .Add(0, drive).Add(0, wgrab).Add(0, wrelease).Add(0, restore).Add(0, remove)
            .Add(0, unassign).bytes);
}

}  // namespace
}  // namespace edgephys::fuzz

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: make_corpus <output dir>\n");
    return 2;
  }
  edgephys::fuzz::g_root = argv[1];
  edgephys::fuzz::PacketCorpus();
  edgephys::fuzz::ReliableCorpus();
  edgephys::fuzz::StateCorpus();
  edgephys::fuzz::MessageCorpus();
  return 0;
}
