// Handshake, tokens, anti-amplification and hostile input against a live relay on loopback.
#include <gtest/gtest.h>

#include <functional>
#include <random>

#include "tests/integration/harness.h"
#include "client/client_testing.h"

namespace edgephys::testing {
namespace {

using schema::RejectReason;

// A raw UDP peer that speaks the handshake by hand.
class RawPeer {
 public:
  explicit RawPeer(LoopbackWorld& world) : world_(world) {
    socket_ = std::move(*UdpSocket::Open(Endpoint(asio::ip::make_address("127.0.0.1"), 0)));
  }

  // Sends `packet`, pumps the relay for a while, returns every datagram that came back.
  std::vector<std::vector<uint8_t>> Exchange(std::span<const uint8_t> packet, double wait_s = 0.03) {
    (void)socket_->SendTo(world_.relay_endpoint(), packet);
    std::vector<std::vector<uint8_t>> replies;
    double end = world_.Now() + wait_s;
    std::vector<uint8_t> buf(2048);
    while (world_.Now() < end) {
      world_.Step();
      Endpoint from;
      while (size_t n = socket_->ReceiveFrom(&from, buf)) replies.emplace_back(buf.begin(), buf.begin() + n);
    }
    return replies;
  }

  std::vector<uint8_t> Hello(uint64_t nonce, size_t pad_to) {
    flatbuffers::FlatBufferBuilder fbb;
    FinishControl(fbb, schema::CreateHello(fbb, nonce));
    return BuildHandshakePacket(PacketType::kHello, fbb, pad_to);
  }
  // A Connect as the SDK sends it for the client token `token`: its relay part, a packet key
  // (the relay seals by default) and the proof under its session secret. Bytes that are not a
  // client token go as they are, with a proof under an all-zero secret.
  std::vector<uint8_t> Connect(std::span<const uint8_t> cookie, std::span<const uint8_t> token,
                               uint64_t nonce) {
    const KeyExchangePublic key = KeyExchange::Generate()->public_key();
    return BuildConnectPacket({nonce, cookie, RelayPart(token), key}, SecretOf(token));
  }
  // A Connect of the previous handshake version: the whole token, no version, no proof.
  std::vector<uint8_t> OldConnect(std::span<const uint8_t> cookie, std::span<const uint8_t> token,
                                  uint64_t nonce) {
    flatbuffers::FlatBufferBuilder fbb;
    const KeyExchangePublic key = KeyExchange::Generate()->public_key();
    FinishControl(fbb, schema::CreateConnect(fbb, fbb.CreateVector(cookie.data(), cookie.size()),
                                             fbb.CreateVector(token.data(), token.size()), nonce,
                                             fbb.CreateVector(key.data(), key.size())));
    return BuildHandshakePacket(PacketType::kConnect, fbb);
  }
  // Runs Hello and returns the cookie (empty on failure).
  std::vector<uint8_t> GetCookie(uint64_t nonce) {
    for (auto& reply : Exchange(Hello(nonce, kMinHelloPacketSize))) {
      const auto* msg = VerifyControlMessage(std::span<const uint8_t>(reply).subspan(kPacketPrefixSize),
                                             schema::Body::Challenge);
      if (msg && msg->body_as_Challenge()->cookie()) {
        auto* c = msg->body_as_Challenge()->cookie();
        return {c->begin(), c->end()};
      }
    }
    return {};
  }
  // Full handshake; returns the Accept's connection id or the Reject reason (as negative).
  // `connect` builds the Connect (default: this peer's Connect()).
  int64_t Handshake(std::span<const uint8_t> token,
                    std::function<std::vector<uint8_t>(std::span<const uint8_t>, uint64_t)> connect = {}) {
    uint64_t nonce = SecureRandom64();
    auto cookie = GetCookie(nonce);
    if (cookie.empty()) return -1000;
    auto packet = connect ? connect(cookie, nonce) : Connect(cookie, token, nonce);
    for (auto& reply : Exchange(packet)) {
      const auto* msg = VerifyControlMessage(std::span<const uint8_t>(reply).subspan(kPacketPrefixSize));
      if (msg == nullptr) continue;
      if (msg->body_type() == schema::Body::Accept) return msg->body_as_Accept()->connection_id();
      if (msg->body_type() == schema::Body::Reject) return -static_cast<int64_t>(msg->body_as_Reject()->reason());
    }
    return -1001;
  }
  void Send(std::span<const uint8_t> packet) { (void)socket_->SendTo(world_.relay_endpoint(), packet); }

 private:
  LoopbackWorld& world_;
  std::unique_ptr<UdpSocket> socket_;
};

TEST(RelayHandshake, NoReplyToUnverifiedAddressIsLargerThanItsRequest) {
  LoopbackWorld world;
  RawPeer peer(world);
  uint64_t nonce = 42;
  auto cookie = peer.GetCookie(nonce);
  ASSERT_EQ(cookie.size(), kCookieSize);

  std::vector<std::vector<uint8_t>> requests;
  requests.push_back(peer.Hello(1, 0));                     // unpadded hello
  requests.push_back(peer.Hello(2, kMinHelloPacketSize - 1));
  requests.push_back(peer.Hello(3, kMinHelloPacketSize));
  requests.push_back(peer.Hello(4, kMaxPacketSize));
  std::vector<uint8_t> bad_cookie(kCookieSize, 7);
  auto token = MintToken("room", 9);
  requests.push_back(peer.Connect(bad_cookie, token, nonce));
  requests.push_back(peer.Connect(cookie, std::vector<uint8_t>{1, 2, 3}, nonce));  // bad token
  requests.push_back(peer.Connect(cookie, MintToken("room", 9, -5), nonce));       // expired
  requests.push_back(peer.Connect(cookie, token, nonce + 1));                       // cookie for another nonce
  for (PacketType t : {PacketType::kChallenge, PacketType::kAccept, PacketType::kReject,
                       PacketType::kData, PacketType::kDisconnect}) {
    std::vector<uint8_t> p(64, 0);
    WritePacketPrefix(t, 12345, p);
    requests.push_back(p);
  }
  requests.push_back(std::vector<uint8_t>(10, 0xff));  // garbage

  int replies_seen = 0;
  for (const auto& request : requests) {
    for (const auto& reply : peer.Exchange(request)) {
      ++replies_seen;
      EXPECT_LE(reply.size(), request.size()) << "amplification: reply to a "
                                              << static_cast<int>(request[5]) << " packet";
    }
  }
  // The good hellos got challenges and the bad tokens got rejects: the test saw replies.
  EXPECT_GE(replies_seen, 4);
  EXPECT_GE(Rejected(world.counters(), DropReason::kHelloTooSmall), 2u);
  EXPECT_GE(Rejected(world.counters(), DropReason::kBadCookie), 2u);
  EXPECT_EQ(world.relay().session_count(), 0u);
}

TEST(RelayHandshake, BadExpiredAndReplayedTokensAreRejectedWithReason) {
  LoopbackWorld world;
  RawPeer peer(world);
  EXPECT_EQ(peer.Handshake(MintToken("room", 5, 3600, kDefaultPermissions, "wrong-secret")),
            -static_cast<int64_t>(RejectReason::BadToken));
  EXPECT_EQ(peer.Handshake(MintToken("room", 5, -1)), -static_cast<int64_t>(RejectReason::ExpiredToken));
  std::vector<uint8_t> garbage(60, 0x5a);
  EXPECT_EQ(peer.Handshake(garbage), -static_cast<int64_t>(RejectReason::BadToken));
  auto tampered = MintToken("room", 5);
  tampered[2] ^= 1;  // player id changed after signing
  EXPECT_EQ(peer.Handshake(tampered), -static_cast<int64_t>(RejectReason::BadToken));

  auto token = MintToken("room", 5);
  EXPECT_GT(peer.Handshake(token), 0);  // accepted
  RawPeer other(world);
  EXPECT_EQ(other.Handshake(token), -static_cast<int64_t>(RejectReason::ReplayedToken));

  ExpectRequestsRejected(world.counters(), {{RejectReason::BadToken, 3},
                                            {RejectReason::ExpiredToken, 1},
                                            {RejectReason::ReplayedToken, 1}});
  EXPECT_EQ(world.relay().session_count(), 1u);
}

// An older SDK's Connect (no handshake version, no proof) gets a Reject naming the cause; a
// Connect whose proof does not match the token's session secret (a man in the middle that
// swapped the client key, or a client holding the wrong secret) gets BadProof. Both counted.
TEST(RelayHandshake, OldVersionsAndBadProofsAreRejectedWithReason) {
  LoopbackWorld world;
  RawPeer peer(world);
  const auto token = MintToken("room", 5);
  const auto relay_part = RelayPart(token);
  EXPECT_EQ(peer.Handshake(token, [&](std::span<const uint8_t> cookie, uint64_t nonce) {
    return peer.OldConnect(cookie, relay_part, nonce);
  }), -static_cast<int64_t>(RejectReason::BadVersion));
  // The right token with a wrong secret.
  EXPECT_EQ(peer.Handshake(token, [&](std::span<const uint8_t> cookie, uint64_t nonce) {
    SessionSecret wrong = SecretOf(token);
    wrong[0] ^= 1;
    return BuildConnectPacket({nonce, cookie, relay_part, KeyExchange::Generate()->public_key()}, wrong);
  }), -static_cast<int64_t>(RejectReason::BadProof));
  // A proof made for one client key, sent with another (the key swapped on the way).
  EXPECT_EQ(peer.Handshake(token, [&](std::span<const uint8_t> cookie, uint64_t nonce) {
    const KeyExchangePublic mine = KeyExchange::Generate()->public_key();
    const KeyExchangePublic swapped = KeyExchange::Generate()->public_key();
    const HandshakeProof proof = ConnectProof(SecretOf(token), {nonce, cookie, relay_part, mine});
    flatbuffers::FlatBufferBuilder fbb;
    FinishControl(fbb, schema::CreateConnect(fbb, fbb.CreateVector(cookie.data(), cookie.size()),
                                             fbb.CreateVector(relay_part), nonce,
                                             fbb.CreateVector(swapped.data(), swapped.size()),
                                             kHandshakeVersion,
                                             fbb.CreateVector(proof.data(), proof.size())));
    return BuildHandshakePacket(PacketType::kConnect, fbb);
  }), -static_cast<int64_t>(RejectReason::BadProof));
  ExpectRequestsRejected(world.counters(),
                         {{RejectReason::BadVersion, 1}, {RejectReason::BadProof, 2}});
  EXPECT_EQ(world.relay().session_count(), 0u);
  // None of them used the token up: the genuine Connect is admitted.
  EXPECT_GT(peer.Handshake(token), 0);
  EXPECT_EQ(world.relay().session_count(), 1u);
}

TEST(RelayHandshake, ClientSdkReportsRejectionAndWrongRoom) {
  LoopbackWorld world;
  Client& expired = world.AddClient(MintToken("room", 1, -60));
  ASSERT_TRUE(world.RunUntil([&] { return expired.state() == ClientState::kRejected; }, 3.0));
  EXPECT_EQ(expired.reject_reason(), static_cast<uint16_t>(RejectReason::ExpiredToken));

  struct ErrorListener : ClientListener {
    uint16_t last = 0;
    void OnError(uint16_t reason, uint32_t, std::string_view) override { last = reason; }
  } listener;
  Client& c = world.AddClient(MintToken("room-a", 2), &listener);
  ASSERT_TRUE(world.RunUntil([&] { return c.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(c.JoinRoom("room-b").ok());
  ASSERT_TRUE(world.RunUntil([&] { return listener.last != 0; }, 3.0));
  EXPECT_EQ(listener.last, static_cast<uint16_t>(RejectReason::WrongRoom));
  EXPECT_FALSE(c.joined());
  EXPECT_EQ(world.relay().FindRoom("room-b"), nullptr);
}

// A join naming no room, or a name longer than any room's, is a malformed request (counted as
// invalid_message), not a room the token lacks; the sender stays in its room.
TEST(RelayHandshake, EmptyOrOversizedRoomNamesAreInvalidMessagesNotWrongRooms) {
  LoopbackWorld world;
  struct ErrorListener : ClientListener {
    std::vector<uint16_t> reasons;
    void OnError(uint16_t reason, uint32_t, std::string_view) override { reasons.push_back(reason); }
  } listener;
  Client& c = world.AddClient(MintToken("room-a", 2), &listener);
  ASSERT_TRUE(world.RunUntil([&] { return c.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(c.JoinRoom("room-a").ok());
  ASSERT_TRUE(world.RunUntil([&] { return c.joined(); }, 3.0));
  EXPECT_FALSE(c.JoinRoom("").ok());  // the SDK refuses it before sending
  const auto invalid = static_cast<size_t>(RejectReason::InvalidMessage);
  const uint64_t before = world.counters().requests_rejected[invalid].load();
  for (const std::string& name : {std::string(), std::string(kMaxRoomNameSize + 1, 'r')}) {
    flatbuffers::FlatBufferBuilder fbb(128);
    FinishControl(fbb, schema::CreateJoinRoom(fbb, fbb.CreateString(name)));
    ASSERT_TRUE(ClientTesting::SendReliableUnchecked(c, {fbb.GetBufferPointer(), fbb.GetSize()}).ok());
  }
  ASSERT_TRUE(world.RunUntil([&] { return listener.reasons.size() == 2; }, 3.0));
  for (uint16_t r : listener.reasons) EXPECT_EQ(r, static_cast<uint16_t>(RejectReason::InvalidMessage));
  EXPECT_EQ(world.counters().requests_rejected[invalid].load(), before + 2);
  EXPECT_TRUE(c.joined());
  ASSERT_NE(world.relay().FindRoom("room-a"), nullptr);
}

TEST(RelayHandshake, RoomCapacityAndServerCapacity) {
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.room_defaults.capacity = 2;
  config.max_clients = 3;
  LoopbackWorld world(config);
  struct ErrorListener : ClientListener {
    uint16_t last = 0;
    void OnError(uint16_t reason, uint32_t, std::string_view) override { last = reason; }
  } listener;
  Client& a = world.AddClient(MintToken("small", 1));
  Client& b = world.AddClient(MintToken("small", 2));
  Client& c = world.AddClient(MintToken("small", 3), &listener);
  ASSERT_TRUE(world.RunUntil([&] {
    return a.state() == ClientState::kConnected && b.state() == ClientState::kConnected &&
           c.state() == ClientState::kConnected;
  }, 3.0));
  for (Client* x : {&a, &b, &c}) ASSERT_TRUE(x->JoinRoom("small").ok());
  ASSERT_TRUE(world.RunUntil([&] { return listener.last != 0; }, 3.0));
  EXPECT_EQ(listener.last, static_cast<uint16_t>(RejectReason::RoomFull));
  EXPECT_TRUE(a.joined());
  EXPECT_TRUE(b.joined());
  EXPECT_FALSE(c.joined());
  Client& d = world.AddClient(MintToken("small", 4));
  ASSERT_TRUE(world.RunUntil([&] { return d.state() == ClientState::kRejected; }, 3.0));
  EXPECT_EQ(d.reject_reason(), static_cast<uint16_t>(RejectReason::ServerFull));
}

TEST(RelayHostileInput, ThousandsOfRandomAndMutatedPacketsNeverBreakTheRelay) {
  // The unsealed parser under mutation (the attacker builds plain data packets); the sealed
  // path: hostile_test.cc and tests/fuzz/packet_fuzz.cc.
  RelayConfig config = LoopbackWorld::DefaultConfig();
  config.packet_auth = false;
  LoopbackWorld world(config);
  RawPeer attacker(world);
  std::mt19937_64 rng(20261121);
  auto byte = [&] { return static_cast<uint8_t>(rng()); };

  // Valid packets to mutate: hellos, connects, and data packets of a live connection.
  Client& victim = world.AddClient(MintToken("fuzz", 1));
  ASSERT_TRUE(world.RunUntil([&] { return victim.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(victim.JoinRoom("fuzz").ok());
  ASSERT_TRUE(world.RunUntil([&] { return victim.joined(); }, 3.0));
  auto victim_id = victim.Spawn({.position = {1, 1, 1}});
  ASSERT_TRUE(victim_id.ok());

  auto attacker_token = MintToken("fuzz", 2);
  int64_t attacker_conn = attacker.Handshake(attacker_token);
  ASSERT_GT(attacker_conn, 0);
  // A connection object on the attacker side produces well-formed data packets to mutate.
  struct Capture : PacketWriter {
    std::vector<std::vector<uint8_t>> packets;
    void WritePacket(std::span<const uint8_t> p) override { packets.emplace_back(p.begin(), p.end()); }
  } capture;
  Connection conn(static_cast<uint32_t>(attacker_conn), ConnectionConfig{}, world.Now());
  {
    flatbuffers::FlatBufferBuilder fbb;
    FinishControl(fbb, schema::CreateJoinRoom(fbb, fbb.CreateString("fuzz")));
    ASSERT_TRUE(conn.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()}).ok());
    conn.Update(world.Now(), capture);
    for (auto& p : capture.packets) attacker.Send(p);
    world.RunFor(0.1);
  }
  std::vector<std::vector<uint8_t>> seeds;
  seeds.push_back(attacker.Hello(7, kMinHelloPacketSize));
  seeds.push_back(attacker.Connect(std::vector<uint8_t>(kCookieSize, 1), attacker_token, 7));
  for (int i = 0; i < 20; ++i) {
    capture.packets.clear();
    flatbuffers::FlatBufferBuilder fbb;
    schema::Transform t(schema::Vec3(1, 2, 3), schema::Quat(0, 0, 0, 1), schema::Vec3(1, 1, 1));
    schema::ContainerBuilder cb(fbb);
    cb.add_entity_id(2 * kEntityIdBlock + static_cast<uint32_t>(i));
    cb.add_owner(2);
    cb.add_transform(&t);
    auto container = cb.Finish();
    FinishControl(fbb, schema::CreateSpawn(fbb, container));
    ASSERT_TRUE(conn.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()}).ok());
    conn.Update(world.Now(), capture);
    uint8_t state[64];
    FloatStateEncoder enc;
    enc.Begin(state, 0);
    enc.Add({*victim_id, {5, 5, 5}, {0, 0, 0, 1}});
    size_t n = enc.Finish();
    (void)conn.SendUnreliable({state, n}, world.Now(), capture);
    for (auto& p : capture.packets) seeds.push_back(p);
  }

  const uint64_t received_before = world.counters().packets_received.load();
  constexpr int kPackets = 6000;
  for (int i = 0; i < kPackets; ++i) {
    std::vector<uint8_t> p;
    switch (rng() % 4) {
      case 0: {  // random bytes, random length (including empty-ish and oversized)
        p.resize(rng() % 1400 + 1);
        for (auto& b : p) b = byte();
        break;
      }
      case 1: {  // valid prefix, random body
        p.resize(kPacketPrefixSize + rng() % 1190);
        for (auto& b : p) b = byte();
        static const PacketType kTypes[] = {PacketType::kHello, PacketType::kConnect,
                                            PacketType::kData, PacketType::kDisconnect};
        WritePacketPrefix(kTypes[rng() % 4], rng() % 2 ? static_cast<uint32_t>(attacker_conn) : 0, p);
        break;
      }
      default: {  // a valid packet with a few bytes flipped, truncated or extended
        p = seeds[rng() % seeds.size()];
        int flips = 1 + static_cast<int>(rng() % 8);
        for (int f = 0; f < flips; ++f) p[rng() % p.size()] ^= static_cast<uint8_t>(1u << (rng() % 8));
        if (rng() % 4 == 0) p.resize(rng() % p.size() + 1);
        if (rng() % 8 == 0) p.resize(p.size() + rng() % 64, byte());
        break;
      }
    }
    attacker.Send(p);
    if (i % 200 == 0) world.Step();
  }
  world.RunFor(0.5);
  EXPECT_GE(world.counters().packets_received.load() - received_before, kPackets * 9u / 10u);
  uint64_t rejected = 0;
  for (auto& r : world.counters().packets_rejected) rejected += r.load();
  EXPECT_GT(rejected, 1000u);
  // The attacker never moved the victim's entity.
  EXPECT_EQ(world.relay().FindRoom("fuzz")->entities().at(*victim_id).state.position.x, 1.0f);

  // The relay still serves honest clients.
  Client& a = world.AddClient(MintToken("after", 10));
  Client& b = world.AddClient(MintToken("after", 11));
  ASSERT_TRUE(ConnectAndJoinAll(world, {&a, &b}, "after", 3.0));
  auto id = a.Spawn({});
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(a.PublishTransform(*id, {3, 2, 1}, {}).ok());
  ASSERT_TRUE(world.RunUntil([&] {
    auto* e = b.FindEntity(*id);
    return e && std::fabs(e->state.position.x - 3.0f) < 0.001f;
  }, 3.0));
  EXPECT_EQ(victim.state(), ClientState::kConnected);
}

TEST(RelayHostileInput, NanAndUnknownEntityUpdatesAreCountedDrops) {
  LoopbackWorld world;
  Client& a = world.AddClient(MintToken("n", 1));
  ASSERT_TRUE(world.RunUntil([&] { return a.state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(a.JoinRoom("n").ok());
  ASSERT_TRUE(world.RunUntil([&] { return a.joined(); }, 3.0));
  auto id = a.Spawn({});
  ASSERT_TRUE(id.ok());
  world.RunFor(0.1);
  EntityState nan_state{*id, {std::nanf(""), 0, 0}, {0, 0, 0, 1}};
  EntityState bad_rotation{*id, {0, 0, 0}, {0, 0, 0, 3}};
  // An id in another player's block: unknown to the room and not this sender's to spawn.
  // (Unknown ids in the sender's own block are held briefly: the spawn may be in flight.)
  EntityState unknown{*id + 5 * kEntityIdBlock, {0, 0, 0}, {0, 0, 0, 1}};
  ASSERT_TRUE(ClientTesting::SendStateUnchecked(a, nan_state, world.Now()).ok());
  world.RunFor(0.02);
  ASSERT_TRUE(ClientTesting::SendStateUnchecked(a, bad_rotation, world.Now()).ok());
  world.RunFor(0.02);
  ASSERT_TRUE(ClientTesting::SendStateUnchecked(a, unknown, world.Now()).ok());
  world.RunFor(0.2);
  EXPECT_EQ(UpdatesRejected(world.counters(), DropReason::kInvalidValue), 2u);
  EXPECT_EQ(UpdatesRejected(world.counters(), DropReason::kUnknownEntity), 1u);
  EXPECT_FALSE(a.PublishTransform(*id, {std::nanf(""), 0, 0}, {}).ok());
  const Entity& e = world.relay().FindRoom("n")->entities().at(*id);
  EXPECT_EQ(e.state.position.x, 0.0f);
}

TEST(RelayHostileInput, AStateThatOvertakesItsSpawnIsAppliedWhenTheSpawnArrives) {
  LoopbackWorld world;
  Client& a = world.AddClient(MintToken("early", 1));
  Client& b = world.AddClient(MintToken("early", 2));
  for (Client* c : {&a, &b}) {
    ASSERT_TRUE(world.RunUntil([&] { return c->state() == ClientState::kConnected; }, 3.0));
    ASSERT_TRUE(c->JoinRoom("early").ok());
  }
  ASSERT_TRUE(world.RunUntil([&] { return a.joined() && b.joined(); }, 3.0));
  // The state for the next id A will spawn goes out before the spawn does.
  uint32_t next_id = a.entity_id_base() + 1;
  ASSERT_TRUE(ClientTesting::SendStateUnchecked(a, {next_id, {7, 8, 9}, {0, 0, 0, 1}}, world.Now()).ok());
  world.RunFor(0.1);
  auto id = a.Spawn({.position = {1, 1, 1}});
  ASSERT_TRUE(id.ok());
  ASSERT_EQ(*id, next_id);
  ASSERT_TRUE(world.RunUntil([&] {
    const RemoteEntity* e = b.FindEntity(next_id);
    return e != nullptr && std::fabs(e->state.position.x - 7.0f) < 0.001f;
  }, 3.0)) << (b.FindEntity(next_id) ? b.FindEntity(next_id)->state.position.x : -1.0f) << " relay "
           << world.relay().FindRoom("early")->entities().at(next_id).state.position.x;
  EXPECT_EQ(UpdatesRejected(world.counters(), DropReason::kUnknownEntity), 0u);
}

}  // namespace
}  // namespace edgephys::testing
