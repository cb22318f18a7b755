// Issue 35 item 7: a man in the middle from the first Hello, with its own X25519 key pairs.
// A real relay on loopback; the victim's SDK talks to it through a UDP proxy in the test that
// forwards every datagram and, depending on its mode, substitutes its own public keys for the
// client's in Connect and for the relay's in Accept (docs/protocol.md §3a, "Threat model").
// A plain forwarding proxy must still work; any substitution must get the connection refused
// with nothing applied to the room.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>

#include "protocol/packet_seal.h"
#include "tests/integration/harness.h"

namespace edgephys::testing {
namespace {

using schema::RejectReason;

class MitmProxy {
 public:
  enum class Mode { kForward, kSwapClientKey, kSwapRelayKey, kSwapBoth };

  MitmProxy(const Endpoint& relay, Mode mode)
      : socket_(std::move(*UdpSocket::Open(Endpoint(relay.address(), 0)))),
        relay_(relay),
        mode_(mode),
        to_client_(std::move(*KeyExchange::Generate())),
        to_relay_(std::move(*KeyExchange::Generate())) {}

  Endpoint endpoint() const { return socket_->LocalEndpoint(); }

  // Moves every pending datagram to the other side, rewriting handshake messages per mode.
  void Pump() {
    Endpoint from;
    while (size_t n = socket_->ReceiveFrom(&from, buffer_)) {
      std::vector<uint8_t> packet(buffer_.begin(), buffer_.begin() + n);
      if (from == relay_) {
        if (!client_) continue;
        if (packet.size() > kPacketPrefixSize && packet[5] == static_cast<uint8_t>(PacketType::kAccept)) {
          RewriteAccept(packet);
        }
        (void)socket_->SendTo(*client_, packet);
      } else {
        client_ = from;
        if (packet.size() > kPacketPrefixSize && packet[5] == static_cast<uint8_t>(PacketType::kConnect)) {
          RewriteConnect(packet);
        }
        (void)socket_->SendTo(relay_, packet);
      }
    }
  }

  // What the man in the middle does once it holds the relay's Accept: it seals a JoinRoom and
  // a state with the best keys it can derive (its own key pair with the relay's public key; it
  // does not know the session secret, so it tries an all-zero one) and sends them as the client.
  // Returns how many it sent (0 before an Accept passed).
  int InjectAsClient(const std::string& room) {
    if (!accept_) return 0;
    Result<ConnectionKeys> keys =
        to_client_.Derive(accept_->relay_key, /*own_is_client=*/true, token_, SessionSecret{},
                          client_nonce_, accept_->connection_id);
    if (!keys.ok()) return 0;
    PacketSeal seal(*keys, PacketSeal::Side::kClient);
    Connection conn(accept_->connection_id, ConnectionConfig{}, 0);
    struct Capture : PacketWriter {
      std::vector<std::vector<uint8_t>> packets;
      void WritePacket(std::span<const uint8_t> p) override { packets.emplace_back(p.begin(), p.end()); }
    } capture;
    flatbuffers::FlatBufferBuilder fbb;
    FinishControl(fbb, schema::CreateJoinRoom(fbb, fbb.CreateString(room)));
    (void)conn.SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
    conn.Update(0, capture);
    int sent = 0;
    for (const auto& p : capture.packets) {
      std::array<uint8_t, kMaxDatagramSize> sealed{};
      const size_t n = seal.Seal(p, sealed);
      if (n > 0 && socket_->SendTo(relay_, std::span(sealed.data(), n)).ok()) ++sent;
    }
    return sent;
  }

  int connects_rewritten = 0;
  int accepts_rewritten = 0;

 private:
  struct AcceptSeen {
    uint32_t connection_id = 0;
    std::vector<uint8_t> relay_key;
  };

  static std::span<const uint8_t> Span(const flatbuffers::Vector<uint8_t>* v) {
    return v ? std::span<const uint8_t>(v->data(), v->size()) : std::span<const uint8_t>();
  }

  void RewriteConnect(std::vector<uint8_t>& packet) {
    const auto* msg = VerifyControlMessage(std::span(packet).subspan(kPacketPrefixSize),
                                           schema::Body::Connect);
    if (msg == nullptr) return;
    const auto* c = msg->body_as_Connect();
    token_.assign(Span(c->token()).begin(), Span(c->token()).end());
    client_nonce_ = c->client_nonce();
    if (mode_ != Mode::kSwapClientKey && mode_ != Mode::kSwapBoth) return;
    // Its own key for the client's, everything else (proof included) as the client sent it.
    const KeyExchangePublic& key = to_relay_.public_key();
    flatbuffers::FlatBufferBuilder fbb(512);
    auto cookie = fbb.CreateVector(Span(c->cookie()).data(), Span(c->cookie()).size());
    auto token = fbb.CreateVector(token_);
    auto swapped = fbb.CreateVector(key.data(), key.size());
    auto proof = fbb.CreateVector(Span(c->proof()).data(), Span(c->proof()).size());
    FinishControl(fbb, schema::CreateConnect(fbb, cookie, token, c->client_nonce(), swapped,
                                             c->version(), proof));
    packet = BuildHandshakePacket(PacketType::kConnect, fbb);
    ++connects_rewritten;
  }

  void RewriteAccept(std::vector<uint8_t>& packet) {
    const auto* msg = VerifyControlMessage(std::span(packet).subspan(kPacketPrefixSize),
                                           schema::Body::Accept);
    if (msg == nullptr) return;
    const auto* a = msg->body_as_Accept();
    accept_ = AcceptSeen{a->connection_id(), {Span(a->relay_key()).begin(), Span(a->relay_key()).end()}};
    if (mode_ != Mode::kSwapRelayKey && mode_ != Mode::kSwapBoth) return;
    const KeyExchangePublic& key = to_client_.public_key();
    flatbuffers::FlatBufferBuilder fbb(256);
    auto swapped = fbb.CreateVector(key.data(), key.size());
    auto proof = fbb.CreateVector(Span(a->proof()).data(), Span(a->proof()).size());
    FinishControl(fbb, schema::CreateAccept(fbb, a->connection_id(), a->player_id(),
                                            a->keepalive_ms(), a->timeout_ms(), swapped, proof));
    packet = BuildHandshakePacket(PacketType::kAccept, fbb);
    ++accepts_rewritten;
  }

  std::unique_ptr<UdpSocket> socket_;
  Endpoint relay_;
  Mode mode_;
  KeyExchange to_client_;  // the key it shows the client as the relay's
  KeyExchange to_relay_;   // the key it shows the relay as the client's
  std::optional<Endpoint> client_;
  std::vector<uint8_t> token_;
  uint64_t client_nonce_ = 0;
  std::optional<AcceptSeen> accept_;
  std::array<uint8_t, 2048> buffer_{};
};

struct Watcher : ClientListener {
  std::vector<uint32_t> joined_players;
  void OnPlayerJoined(uint32_t player_id) override { joined_players.push_back(player_id); }
};

// The room "r" with an honest member B connected directly, and the victim A (player 7)
// connecting through a proxy in `mode`.
class MitmTest : public ::testing::Test {
 protected:
  void Start(MitmProxy::Mode mode) {
    proxy_ = std::make_unique<MitmProxy>(world_.relay_endpoint(), mode);
    watcher_ = &world_.AddClient(MintToken("r", 2), &watch_);
    ASSERT_TRUE(ConnectAndJoinAll(world_, {watcher_}, "r", 3.0));
    victim_socket_ = std::move(*UdpSocket::Open(Endpoint(world_.relay_endpoint().address(), 0)));
    victim_ = std::make_unique<Client>(ClientConfig{}, victim_socket_.get());
    ASSERT_TRUE(victim_->Connect(ToRelayAddress(proxy_->endpoint()), MintToken("r", kVictim),
                                 world_.Now())
                    .ok());
  }
  bool Run(const std::function<bool()>& done, double timeout_s) {
    return world_.RunUntil([&] {
      proxy_->Pump();
      victim_->Update(world_.Now());
      proxy_->Pump();
      return done();
    }, timeout_s);
  }
  // Starts the proxy in `mode` and waits (3 s) until the victim's handshake ends, which must
  // be refused with BadProof. Fails fatally if the handshake does not end.
  void StartAndExpectBadProof(MitmProxy::Mode mode) {
    Start(mode);
    ASSERT_TRUE(Run([&] { return victim_->state() != ClientState::kHandshaking; }, 3.0));
    EXPECT_EQ(victim_->state(), ClientState::kRejected);
    EXPECT_EQ(victim_->reject_reason(), static_cast<uint16_t>(RejectReason::BadProof));
  }
  size_t RoomSize() {
    const Room* room = world_.relay().FindRoom("r");
    return room ? room->size() : 0;
  }

  static constexpr uint32_t kVictim = 7;
  LoopbackWorld world_;
  Watcher watch_;
  Client* watcher_ = nullptr;
  std::unique_ptr<MitmProxy> proxy_;
  std::unique_ptr<UdpSocket> victim_socket_;
  std::unique_ptr<Client> victim_;
};

TEST_F(MitmTest, APlainForwardingProxyStillConnectsAndStatesArriveIntact) {
  Start(MitmProxy::Mode::kForward);
  ASSERT_TRUE(Run([&] { return victim_->state() == ClientState::kConnected; }, 3.0));
  ASSERT_TRUE(victim_->JoinRoom("r").ok());
  ASSERT_TRUE(Run([&] { return victim_->joined(); }, 3.0));
  auto id = victim_->Spawn({.position = {1, 2, 3}});
  ASSERT_TRUE(id.ok());
  ASSERT_TRUE(victim_->PublishTransform(*id, {4, 5, 6}, {0, 0, 0, 1}).ok());
  ASSERT_TRUE(Run([&] {
    const RemoteEntity* e = watcher_->FindEntity(*id);
    return e != nullptr && e->has_state && std::abs(e->state.position.x - 4.0f) < 0.01f;
  }, 3.0));
  const RemoteEntity* seen = watcher_->FindEntity(*id);
  EXPECT_EQ(seen->owner, kVictim);
  EXPECT_NEAR(seen->state.position.y, 5.0f, 0.01f);
  EXPECT_NEAR(seen->state.position.z, 6.0f, 0.01f);
  EXPECT_EQ(RequestsRejected(world_.counters(), RejectReason::BadProof), 0u);
  EXPECT_EQ(proxy_->connects_rewritten + proxy_->accepts_rewritten, 0);
}

// The man in the middle shows each side its own key: the relay refuses the Connect (its proof
// was made for the client's key) and the victim hears that refusal.
TEST_F(MitmTest, SubstitutingBothKeysGetsTheConnectRefused) {
  ASSERT_NO_FATAL_FAILURE(StartAndExpectBadProof(MitmProxy::Mode::kSwapBoth));
  EXPECT_GE(proxy_->connects_rewritten, 1);
  EXPECT_GE(RequestsRejected(world_.counters(), RejectReason::BadProof), 1u);
  EXPECT_EQ(world_.relay().session_count(), 1u);  // the watcher's only
  EXPECT_EQ(proxy_->InjectAsClient("r"), 0);     // no Accept ever passed
  EXPECT_EQ(RoomSize(), 1u);
  EXPECT_TRUE(watch_.joined_players.empty());
}

// The same with only the client's key swapped (the relay's Accept would have been passed on).
TEST_F(MitmTest, SubstitutingTheClientKeyGetsTheConnectRefused) {
  ASSERT_NO_FATAL_FAILURE(StartAndExpectBadProof(MitmProxy::Mode::kSwapClientKey));
  EXPECT_EQ(world_.relay().session_count(), 1u);
}

// The Connect passes untouched (the relay admits it) and the Accept's key is swapped: the SDK
// refuses the Accept, and what the man in the middle then sends the relay as the client, sealed
// with every key it can derive, is dropped: the room never sees the victim.
TEST_F(MitmTest, SubstitutingTheRelayKeyGetsTheAcceptRefusedAndNothingApplied) {
  ASSERT_NO_FATAL_FAILURE(StartAndExpectBadProof(MitmProxy::Mode::kSwapRelayKey));
  EXPECT_GE(proxy_->accepts_rewritten, 1);
  const uint64_t bad_auth = Rejected(world_.counters(), DropReason::kBadAuth);
  ASSERT_GT(proxy_->InjectAsClient("r"), 0);
  ASSERT_TRUE(Run([&] { return Rejected(world_.counters(), DropReason::kBadAuth) > bad_auth; }, 2.0));
  world_.RunFor(0.2);
  EXPECT_EQ(RoomSize(), 1u);
  EXPECT_TRUE(watch_.joined_players.empty());
  EXPECT_TRUE(watcher_->entities().empty());
}

}  // namespace
}  // namespace edgephys::testing
