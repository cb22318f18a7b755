// Relay: the handshake (Hello -> Challenge, Connect -> Accept or Reject) and admission of a new
// session: cookie check, handshake version, join-token verification, the client's proof of the
// token's session secret, cluster routing, limits (draining, packet authentication, capacity,
// connections per address, token replay), the per-connection keys and the relay's own proof.
// Replies to unverified addresses are never larger than the request (no amplification).
// The rest of Relay is in relay.cc.
#include <spdlog/spdlog.h>

#include "relay/cluster_hook.h"
#include "relay/drop_log.h"
#include "relay/relay.h"

namespace edgephys {
namespace {

using schema::RejectReason;

uint16_t Code(RejectReason r) { return static_cast<uint16_t>(r); }

DropLog& Log() { return DropLogOfThisThread(); }

}  // namespace

void Relay::HandleHello(const Endpoint& from, std::span<const uint8_t> data, double now) {
  if (data.size() < kMinHelloPacketSize) {
    counters_->RejectPacket(DropReason::kHelloTooSmall);
    Log().Note("hello dropped", DropReasonName(DropReason::kHelloTooSmall), from, now);
    return;
  }
  const auto* msg = VerifyControlMessage(data.subspan(kPacketPrefixSize), schema::Body::Hello);
  if (msg == nullptr) {
    counters_->RejectPacket(DropReason::kMalformed);
    return;
  }
  auto cookie = cookies_.Issue(from, msg->body_as_Hello()->client_nonce(), now);
  flatbuffers::FlatBufferBuilder fbb(128);
  FinishControl(fbb, schema::CreateChallenge(fbb, fbb.CreateVector(cookie.data(), cookie.size())));
  auto packet = BuildHandshakePacket(PacketType::kChallenge, fbb);
  SendUnverified(from, packet, data.size());
}

void Relay::HandleConnect(const Endpoint& from, std::span<const uint8_t> data, double now,
                          uint64_t unix_now_s) {
  const auto* msg = VerifyControlMessage(data.subspan(kPacketPrefixSize), schema::Body::Connect);
  if (msg == nullptr) {
    counters_->RejectPacket(DropReason::kMalformed);
    return;
  }
  const auto* connect = msg->body_as_Connect();
  const auto* cookie = connect->cookie();
  if (cookie == nullptr ||
      !cookies_.Verify(std::span<const uint8_t>(cookie->data(), cookie->size()), from,
                       connect->client_nonce(), now)) {
    // The address is unverified: no answer at all.
    counters_->RejectPacket(DropReason::kBadCookie);
    Log().Note("connect dropped", DropReasonName(DropReason::kBadCookie), from, now);
    return;
  }
  if (connect->version() != kHandshakeVersion) {  // an older SDK: it cannot prove a secret
    Log().Note("connect rejected", "BadVersion", from, now);
    return SendReject(from, Code(RejectReason::BadVersion), data.size());
  }
  std::span<const uint8_t> token_bytes;
  if (connect->token() != nullptr) {
    token_bytes = std::span<const uint8_t>(connect->token()->data(), connect->token()->size());
  }
  std::span<const uint8_t> client_key;
  if (connect->client_key() != nullptr) {
    client_key = std::span<const uint8_t>(connect->client_key()->data(), connect->client_key()->size());
  }
  Result<JoinToken> token = VerifyJoinToken(token_bytes, config_.secret, unix_now_s);
  if (!token.ok()) {
    RejectReason r = IsExpiredToken(token.status()) ? RejectReason::ExpiredToken
                                                    : RejectReason::BadToken;
    Log().Note("connect rejected", schema::EnumNameRejectReason(r), from, now);
    return SendReject(from, Code(r), data.size());
  }
  // The client proves it holds the session secret sealed in the token and binds its key to
  // it: a man in the middle that swapped the key (or replays the token it saw) fails here.
  const HandshakeProof connect_proof =
      ConnectProof(token->session_secret,
                   {connect->client_nonce(), std::span<const uint8_t>(cookie->data(), cookie->size()),
                    token_bytes, client_key});
  if (!ProofMatches(connect->proof(), connect_proof)) {
    Log().Note("connect rejected", "BadProof", from, now);
    return SendReject(from, Code(RejectReason::BadProof), data.size());
  }
  if (cluster_) {  // the room may live on another relay of the cluster
    std::vector<uint8_t> redirect;
    switch (cluster_->RouteConnect(*token, token_bytes, unix_now_s, &redirect)) {
      case ClusterHook::Route::kLocal: break;
      case ClusterHook::Route::kRedirected: return Transmit(from, redirect);  // cookie-verified
      case ClusterHook::Route::kDeferred: return;  // the client repeats its Connect
    }
  }

  // The same client repeating its Connect because our Accept was lost: repeat the Accept.
  if (auto it = session_by_endpoint_.find(from); it != session_by_endpoint_.end()) {
    Session& existing = *sessions_.at(it->second);
    if (existing.token_nonce() == token->nonce) {
      Transmit(from, existing.accept_packet());
      return;
    }
    // Another token from an address that holds a live session. Anyone who can send from that
    // address (a spoofer that reads the Challenge) can get this far, so it never ends the
    // session: only what proves the session's keys does (a sealed Disconnect, or the silence
    // timeout of a client that restarted without saying so). Refused and counted.
    if (existing.connection().connected()) {
      counters_->RejectPacket(DropReason::kSessionHeld);
      Log().Note("connect rejected", DropReasonName(DropReason::kSessionHeld), from, now);
      return SendReject(from, Code(RejectReason::RateLimited), data.size());
    }
  }
  if (!admitting_) {  // draining
    Log().Note("connect rejected", "relay draining", from, now);
    return SendReject(from, Code(RejectReason::ServerFull), data.size());
  }
  if (config_.packet_auth && client_key.size() != kKeyExchangePublicSize) {
    Log().Note("connect rejected", "no packet key", from, now);
    return SendReject(from, Code(RejectReason::AuthRequired), data.size());
  }
  if (sessions_.size() >= config_.max_clients) {
    return SendReject(from, Code(RejectReason::ServerFull), data.size());
  }
  if (config_.limits.max_sessions_per_address > 0) {
    size_t same_address = 0;
    for (const auto& [id, other] : sessions_) same_address += other->endpoint().address() == from.address();
    if (same_address >= config_.limits.max_sessions_per_address) {
      Log().Note("connect rejected", "too many connections from one address", from, now);
      return SendReject(from, Code(RejectReason::RateLimited), data.size());
    }
  }
  Status admitted = replay_guard_.Admit(token->nonce, token->expiry_unix_s, unix_now_s);
  if (!admitted.ok()) {
    RejectReason r = admitted.code() == StatusCode::kAlreadyExists ? RejectReason::ReplayedToken
                                                                   : RejectReason::ServerFull;
    Log().Note("connect rejected", schema::EnumNameRejectReason(r), from, now);
    return SendReject(from, Code(r), data.size());
  }

  Admit(from, *token, token_bytes, config_.packet_auth ? client_key : std::span<const uint8_t>(),
        connect->client_nonce(), connect_proof, now);
}

void Relay::Admit(const Endpoint& from, const JoinToken& token, std::span<const uint8_t> token_bytes,
                  std::span<const uint8_t> client_key, uint64_t client_nonce,
                  const HandshakeProof& connect_proof, double now) {
  uint32_t connection_id = 0;
  while (connection_id == 0 || sessions_.count(connection_id) != 0) {
    connection_id = static_cast<uint32_t>(SecureRandom64());
    if (shard_.count > 1) {  // the id's residue names this shard (0 if it would overflow)
      uint64_t id = connection_id - connection_id % shard_.count + uint64_t{shard_.index};
      connection_id = id > UINT32_MAX ? 0 : static_cast<uint32_t>(id);
    }
  }
  SessionHost* host = this;
  auto session = std::make_unique<Session>(host, counters_, from, connection_id, token.player_id,
                                           token.permissions, token.room, token.nonce,
                                           config_.connection, config_.limits, now);
  flatbuffers::FlatBufferBuilder fbb(192);
  flatbuffers::Offset<flatbuffers::Vector<uint8_t>> relay_key;
  AcceptTranscript accept{connect_proof,
                          {},
                          connection_id,
                          token.player_id,
                          static_cast<uint32_t>(config_.connection.keepalive_interval_s * 1000),
                          static_cast<uint32_t>(config_.connection.timeout_s * 1000)};
  KeyExchangePublic relay_public{};
  if (!client_key.empty()) {  // packet authentication: this connection's keys
    Result<KeyExchange> generated = KeyExchange::Generate();
    Result<ConnectionKeys> keys =
        generated.ok() ? generated->Derive(client_key, /*own_is_client=*/false, token_bytes,
                                           token.session_secret, client_nonce, connection_id)
                       : Result<ConnectionKeys>(generated.status());
    if (!keys.ok()) {
      Log().Note("connect rejected", "bad packet key", from, now);
      return SendReject(from, Code(RejectReason::AuthRequired), kMaxPacketSize);  // verified
    }
    session->EnableSeal(*keys);
    relay_public = generated->public_key();
    accept.relay_key = relay_public;
    relay_key = fbb.CreateVector(relay_public.data(), relay_public.size());
  }
  const HandshakeProof proof = AcceptProof(token.session_secret, accept);
  FinishControl(fbb, schema::CreateAccept(fbb, connection_id, token.player_id, accept.keepalive_ms,
                                          accept.timeout_ms, relay_key,
                                          fbb.CreateVector(proof.data(), proof.size())));
  session->accept_packet() = BuildHandshakePacket(PacketType::kAccept, fbb);
  Transmit(from, session->accept_packet());
  session_by_endpoint_[from] = connection_id;
  sessions_[connection_id] = std::move(session);
  due_sessions_.push_back(connection_id);  // born due (Session::service_at)
  RelayCounters::Inc(counters_->connections_accepted);
  spdlog::info("player {} connected from {}:{} (connection {:08x})", token.player_id,
               from.address().to_string(), from.port(), connection_id);
}

void Relay::SendReject(const Endpoint& to, uint16_t reason, size_t request_size) {
  counters_->RejectRequest(reason);
  flatbuffers::FlatBufferBuilder fbb(64);
  FinishControl(fbb, schema::CreateReject(fbb, static_cast<RejectReason>(reason)));
  auto packet = BuildHandshakePacket(PacketType::kReject, fbb);
  SendUnverified(to, packet, request_size);
}

void Relay::SendUnverified(const Endpoint& to, std::span<const uint8_t> reply,
                           size_t request_size) {
  if (reply.size() > request_size) {
    // Never amplify towards an address that has not proven it owns itself.
    counters_->RejectPacket(DropReason::kHelloTooSmall);
    return;
  }
  Transmit(to, reply);
}

}  // namespace edgephys
