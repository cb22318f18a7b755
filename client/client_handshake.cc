// Client SDK: the handshake (docs/protocol.md §2): Connect() splits the client token, Hello and
// Connect (with this client's key and its proof of the session secret) are sent until
// answered, the relay's Accept is checked against its proof before any key is derived, and
// Redirects and resumes restart the handshake elsewhere with the same token.
#include <time.h>

#include "client/client_endpoint.h"
#include "client/client_impl.h"
#include "protocol/endpoint.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "protocol/redirect.h"

namespace edgephys {
namespace {

uint64_t UnixNowS() {
  timespec now{};
  clock_gettime(CLOCK_REALTIME, &now);
  return static_cast<uint64_t>(now.tv_sec);
}

std::span<const uint8_t> Bytes(const flatbuffers::Vector<uint8_t>* v) {
  return v ? std::span<const uint8_t>(v->data(), v->size()) : std::span<const uint8_t>();
}

}  // namespace

Status Client::Impl::Connect(const RelayAddress& address, std::span<const uint8_t> token,
                             double now) {
  if (state_ != ClientState::kIdle) {
    return Status::InvalidArgument("Connect() called twice");
  }
  Result<Endpoint> server = ToEndpoint(address);
  if (!server.ok()) return server.status();
  std::vector<Endpoint> relays;
  for (const RelayAddress& r : config_.relays) {
    Result<Endpoint> e = ToEndpoint(r);
    if (!e.ok()) return e.status();
    relays.push_back(*e);
  }
  // The relay part goes into Connect; the session secret stays here.
  Result<ClientToken> split = SplitClientToken(token);
  if (!split.ok()) return split.status();
  relays_ = std::move(relays);
  server_ = *server;
  entry_server_ = *server;
  redirects_this_handshake_ = 0;
  token_.assign(split->relay_token.begin(), split->relay_token.end());
  session_secret_ = split->session_secret;
  nonce_ = SecureRandom64();
  Result<KeyExchange> kx = KeyExchange::Generate();
  if (!kx.ok()) return kx.status();
  key_exchange_ = std::make_unique<KeyExchange>(std::move(*kx));
  state_ = ClientState::kHandshaking;
  handshake_started_ = now;
  // false (no arrival times from this socket) is handled per datagram: Update() takes the time
  // of the read instead and counts it in arrival_time_fallbacks().
  if (config_.record_arrival_times) (void)socket_->EnableArrivalTimes();
  SendHandshake(now);
  return Status::Ok();
}

void Client::Impl::SendHandshake(double now) {
  last_handshake_send_ = now;
  if (cookie_.empty()) {
    flatbuffers::FlatBufferBuilder fbb(64);
    FinishControl(fbb, schema::CreateHello(fbb, nonce_));
    auto packet = BuildHandshakePacket(PacketType::kHello, fbb, kMinHelloPacketSize);
    // A lost Hello is like a lost datagram: Update() sends it again after handshake_resend_s.
    (void)socket_->SendTo(server_, packet);
  } else {
    if (key_exchange_ == nullptr) return;  // no key pair (generation failed): cannot Connect
    // The proof covers this nonce, the cookie, the token and the key; Accept's chains to it.
    auto packet = BuildConnectPacket({nonce_, cookie_, token_, key_exchange_->public_key()},
                                     session_secret_, &connect_proof_);
    // As for Hello: resent until answered.
    (void)socket_->SendTo(server_, packet);
  }
}

void Client::Impl::HandleHandshakePacket(std::span<const uint8_t> packet, double now) {
  if (state_ != ClientState::kHandshaking) return;
  PacketPrefix prefix{};
  DropReason reason{};
  ParsePacketPrefix(packet, &prefix, &reason);
  const auto* msg = VerifyControlMessage(packet.subspan(kPacketPrefixSize));
  if (msg == nullptr) return;
  if (prefix.type == PacketType::kChallenge && msg->body_type() == schema::Body::Challenge) {
    const auto* cookie = msg->body_as_Challenge()->cookie();
    if (cookie == nullptr || !cookie_.empty()) return;
    cookie_.assign(cookie->begin(), cookie->end());
    SendHandshake(now);
  } else if (prefix.type == PacketType::kAccept && msg->body_type() == schema::Body::Accept) {
    const auto* accept = msg->body_as_Accept();
    if (cookie_.empty()) return;  // no Connect sent yet: not an answer to ours
    ConnectionConfig cc = config_.connection;
    if (accept->keepalive_ms() > 0) cc.keepalive_interval_s = accept->keepalive_ms() / 1000.0;
    if (accept->timeout_ms() > 0) cc.timeout_s = accept->timeout_ms() / 1000.0;
    const auto* relay_key = accept->relay_key();
    if (relay_key == nullptr && config_.require_packet_auth) {
      if (resuming_) return;  // as a Reject while resuming: try the next relay
      // A downgrade (or a relay without --packet-auth): refuse it, and tell the relay.
      std::vector<uint8_t> bye(kConnectionHeaderSize + 1, 0);
      WritePacketPrefix(PacketType::kDisconnect, accept->connection_id(), bye);
      bye.back() = static_cast<uint8_t>(DisconnectReason::kClientLeft);
      (void)socket_->SendTo(server_, bye);
      key_exchange_.reset();
      reject_reason_ = static_cast<uint16_t>(schema::RejectReason::AuthRequired);
      state_ = ClientState::kRejected;
      listener_->OnRejected(reject_reason_);
      return;
    }
    // The relay proves it read the session secret from the token, over everything this
    // Accept says and the Connect it answers: a man in the middle that swapped either key
    // cannot. Checked whenever a proof is present; required unless packet authentication was
    // turned off (an unsealed measurement relay is then accepted without one).
    const HandshakeProof expected = AcceptProof(
        session_secret_, {connect_proof_, Bytes(relay_key), accept->connection_id(),
                          accept->player_id(), accept->keepalive_ms(), accept->timeout_ms()});
    if ((accept->proof() != nullptr || config_.require_packet_auth) &&
        !ProofMatches(accept->proof(), expected)) {
      if (resuming_) return;  // as a Reject while resuming: try the next relay
      // Nothing is sent: this peer holds no keys we could share.
      key_exchange_.reset();
      reject_reason_ = static_cast<uint16_t>(schema::RejectReason::BadProof);
      state_ = ClientState::kRejected;
      listener_->OnRejected(reject_reason_);
      return;
    }
    if (relay_key != nullptr) {
      Result<ConnectionKeys> keys = key_exchange_->Derive(
          Bytes(relay_key), /*own_is_client=*/true, token_, session_secret_, nonce_,
          accept->connection_id());
      if (!keys.ok()) return;  // a degenerate key (proof matched, so the relay's own fault)
      seal_ = std::make_unique<PacketSeal>(*keys, PacketSeal::Side::kClient);
      seal_buffer_.resize(kMaxDatagramSize);
      open_buffer_.resize(kMaxDatagramSize);
    }
    key_exchange_.reset();
    connection_ = std::make_unique<Connection>(accept->connection_id(), cc, now);
    unreliable_.sent = 0;  // the relay orders unreliable messages per connection
    if (seal_) connection_->SetDatagramOverhead(kSealOverhead);  // count the sealed datagrams
    player_id_ = accept->player_id();
    state_ = ClientState::kConnected;
    if (resuming_) {  // transparent: rejoin the room at once
      (void)JoinRoom(resume_room_);
      return;
    }
    listener_->OnConnected(player_id_);
  } else if (prefix.type == PacketType::kReject && msg->body_type() == schema::Body::Redirect) {
    HandleRedirect(*msg, now);
  } else if (prefix.type == PacketType::kReject && msg->body_type() == schema::Body::Reject) {
    if (resuming_) return;  // e.g. a relay that does not know the room yet: try the next one
    reject_reason_ = static_cast<uint16_t>(msg->body_as_Reject()->reason());
    state_ = ClientState::kRejected;
    listener_->OnRejected(reject_reason_);
  }
}

void Client::Impl::RestartHandshake(const Endpoint& server, double now) {
  server_ = server;
  cookie_.clear();
  nonce_ = SecureRandom64();
  // A new handshake (a redirect, or a resume on another relay) agrees new packet keys: a fresh
  // key pair, and the previous connection's seal is dropped. The token and its session secret
  // stay.
  seal_.reset();
  if (Result<KeyExchange> kx = KeyExchange::Generate(); kx.ok()) {
    key_exchange_ = std::make_unique<KeyExchange>(std::move(*kx));
  }
  handshake_started_ = now;
  state_ = ClientState::kHandshaking;
  SendHandshake(now);
}

void Client::Impl::HandleRedirect(const schema::ControlMessage& msg, double now) {
  auto ticket = ParseRedirect(*msg.body_as_Redirect());
  if (!ticket.ok() || redirects_this_handshake_ >= config_.max_redirects ||
      !VerifyRedirect(*ticket, token_, session_secret_, UnixNowS()).ok()) {
    ++redirects_refused_;  // forged, expired or a loop: keep waiting for a real answer
    return;
  }
  auto target = ParseEndpoint(ticket->address);
  if (!target.ok()) {
    ++redirects_refused_;
    return;
  }
  ++redirects_this_handshake_;
  ++redirects_followed_;
  RestartHandshake(*target, now);
}

}  // namespace edgephys
