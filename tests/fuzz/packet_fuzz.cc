// packet_fuzz: the packet parser and every datagram path, relay and client.
//
// Input: u8 setup | records (u8 tag | u16 length | bytes), at most kMaxRecords. setup bit 0:
// first connect a real client A and join it to a room (a live session on the relay). Each
// record is parsed directly (ParsePacketPrefix, VerifyControlMessage for every handshake
// body) and then sent, by tag % 5, as:
//   0: a datagram from a stranger's address to the relay (handshake, unknown connections)
//   1: a datagram from A's address to the relay, as is (tag bit 3: A's last sealed data
//      packet with the bytes XORed over it from offset 10: a replay when they are empty or
//      zero, else a forgery of the authenticated path with A's address and connection id)
//   2: A's address, with a valid prefix (tag bit 3: kDisconnect, else kData) and A's
//      connection id prepended: the bytes reach Connection::ProcessPacket and the session's
//      message handlers
//   3: a datagram from the relay's address to A (tag bit 3: prefix with A's id prepended):
//      the client SDK's datagram path
//   4: a datagram from a silent server to client B, which is mid-handshake: the client's
//      handshake handling, proof checks included (tag bit 3: a handshake prefix of type
//      tag >> 4 prepended)
// The relay and the clients are pumped one fake-clock step after each record. Every record is
// also opened by a PacketSeal (must refuse it, never crash) and sealed and opened again (must
// round-trip).
#include <cstddef>
#include <cstdint>

#include "client/client_endpoint.h"
#include "tests/fuzz/fuzz_world.h"

namespace edgephys::fuzz {
namespace {

constexpr size_t kMaxRecords = 64;

// The AEAD layer alone: arbitrary bytes never open under a key; sealed ones open once, intact.
void SealDirectly(std::span<const uint8_t> bytes) {
  static ConnectionKeys keys = [] {
    ConnectionKeys k;
    for (size_t i = 0; i < k.client_to_relay.size(); ++i) k.client_to_relay[i] = uint8_t(i);
    for (size_t i = 0; i < k.relay_to_client.size(); ++i) k.relay_to_client[i] = uint8_t(3 * i);
    return k;
  }();
  PacketSeal client(keys, PacketSeal::Side::kClient), relay(keys, PacketSeal::Side::kRelay);
  std::vector<uint8_t> out(kMaxDatagramSize + 64), sealed(kMaxDatagramSize);
  DropReason reason{};
  EDGEPHYS_FUZZ_CHECK(relay.Open(bytes, out, &reason) == 0);
  if (bytes.size() < kPacketPrefixSize || bytes.size() > kMaxPacketSize) return;
  const size_t n = client.Seal(bytes, sealed);
  EDGEPHYS_FUZZ_CHECK(n == bytes.size() + kSealOverhead);
  EDGEPHYS_FUZZ_CHECK(relay.Open({sealed.data(), n}, out, &reason) == bytes.size());
  EDGEPHYS_FUZZ_CHECK(std::equal(bytes.begin(), bytes.end(), out.begin()));
  EDGEPHYS_FUZZ_CHECK(relay.Open({sealed.data(), n}, out, &reason) == 0);  // replay
}

void ParseDirectly(std::span<const uint8_t> bytes) {
  PacketPrefix prefix{};
  DropReason reason{};
  bool ok = ParsePacketPrefix(bytes, &prefix, &reason);
  if (!ok) EDGEPHYS_FUZZ_CHECK(reason < DropReason::kCount);
  (void)DropReasonName(reason);
  if (bytes.size() < kPacketPrefixSize) return;
  auto payload = bytes.subspan(kPacketPrefixSize);
  for (schema::Body body : {schema::Body::NONE, schema::Body::Hello, schema::Body::Challenge,
                            schema::Body::Connect, schema::Body::Accept, schema::Body::Reject}) {
    const schema::ControlMessage* msg = VerifyControlMessage(payload, body);
    if (msg == nullptr) continue;
    // A verified message may be read freely.
    switch (msg->body_type()) {
      case schema::Body::Hello: (void)msg->body_as_Hello()->client_nonce(); break;
      case schema::Body::Challenge:
        if (auto* c = msg->body_as_Challenge()->cookie()) (void)std::vector<uint8_t>(c->begin(), c->end());
        break;
      case schema::Body::Connect: {
        const auto* c = msg->body_as_Connect();
        if (c->token() != nullptr) {
          TokenError error;
          std::span<const uint8_t> token(c->token()->data(), c->token()->size());
          auto verified = VerifyJoinToken(token, kFuzzSecret, kUnixNow, &error);
          // The relay's proof check on whatever the message holds (absent fields: empty).
          auto span_of = [](const flatbuffers::Vector<uint8_t>* v) {
            return v ? std::span<const uint8_t>(v->data(), v->size()) : std::span<const uint8_t>();
          };
          const HandshakeProof proof = ConnectProof(
              verified.ok() ? verified->session_secret : SessionSecret{},
              {c->client_nonce(), span_of(c->cookie()), token, span_of(c->client_key())});
          (void)ProofMatches(c->proof(), proof);
        }
        break;
      }
      case schema::Body::Accept: {
        const auto* a = msg->body_as_Accept();
        (void)ProofMatches(a->proof(), AcceptProof(SessionSecret{}, {{}, {}, a->connection_id(),
                                                                     a->player_id(), 0, 0}));
        break;
      }
      case schema::Body::Reject: (void)msg->body_as_Reject()->reason(); break;
      default: break;
    }
  }
}

std::vector<uint8_t> WithPrefix(PacketType type, uint32_t connection_id,
                                std::span<const uint8_t> rest) {
  std::vector<uint8_t> out(kPacketPrefixSize + rest.size());
  WritePacketPrefix(type, connection_id, out);
  std::copy(rest.begin(), rest.end(), out.begin() + kPacketPrefixSize);
  return out;
}

}  // namespace
}  // namespace edgephys::fuzz

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace edgephys;
  using namespace edgephys::fuzz;
  Reader in(data, size);
  const uint8_t setup = in.U8();

  World world;
  Client& a = world.AddClient(1, kDefaultPermissions);
  const bool session = (setup & 1) != 0;
  if (session && !world.ConnectAndJoin(a)) std::abort();  // the harness itself is broken

  // Client B: handshaking with a server that never answers on its own.
  const Endpoint silent_server = Ep("10.0.0.1", 7778);
  auto silent_socket = world.network().CreateSocket(silent_server);
  auto b_socket = world.network().CreateSocket(Ep("10.0.2.3", 40000));
  Client b(ClientConfig{}, b_socket.get());
  auto b_token = MintToken(2, kDefaultPermissions);
  (void)b.Connect(ToRelayAddress(silent_server), b_token, world.now());

  auto stranger = world.network().CreateSocket(Ep("10.0.0.9", 5555));
  for (size_t i = 0; i < kMaxRecords && !in.empty(); ++i) {
    const uint8_t tag = in.U8();
    const size_t len = in.U16();
    auto bytes = in.Bytes(len);
    ParseDirectly(bytes);
    SealDirectly(bytes);
    const bool alt = (tag & 8) != 0;
    const uint32_t a_id = world.client_socket(0).connection_id();
    switch (tag % 5) {
      case 0:
        (void)stranger->SendTo(world.relay_endpoint(), bytes);
        break;
      case 1:
        if (alt && !world.client_socket(0).last_data().empty()) {
          std::vector<uint8_t> forged = world.client_socket(0).last_data();
          for (size_t k = 0; k < bytes.size() && kPacketPrefixSize + k < forged.size(); ++k) {
            forged[kPacketPrefixSize + k] ^= bytes[k];
          }
          (void)world.client_socket(0).SendUntapped(world.relay_endpoint(), forged);
        } else {
          (void)world.client_socket(0).SendUntapped(world.relay_endpoint(), bytes);
        }
        break;
      case 2: {
        auto packet = WithPrefix(alt ? PacketType::kDisconnect : PacketType::kData, a_id, bytes);
        (void)world.client_socket(0).SendUntapped(world.relay_endpoint(), packet);
        break;
      }
      case 3: {
        const Endpoint a_ep = world.client_socket(0).LocalEndpoint();
        if (alt) {
          auto packet = WithPrefix(PacketType::kData, a_id, bytes);
          (void)world.relay_socket().SendTo(a_ep, packet);
        } else {
          (void)world.relay_socket().SendTo(a_ep, bytes);
        }
        break;
      }
      case 4: {
        if (alt) {
          auto packet = WithPrefix(static_cast<PacketType>(tag >> 4), 0, bytes);
          (void)silent_socket->SendTo(b_socket->LocalEndpoint(), packet);
        } else {
          (void)silent_socket->SendTo(b_socket->LocalEndpoint(), bytes);
        }
        break;
      }
    }
    world.Step();
    b.Update(world.now());
  }
  // Let resends, acks and the relay's replies play out.
  for (int i = 0; i < 3; ++i) {
    world.Step();
    b.Update(world.now());
  }
  return 0;
}
