// Client's public methods (forwarders to Client::Impl, client/client_impl.h), the RelayAddress
// helpers of client.h and client_endpoint.h, and ClientTesting (client_testing.h).
#include <utility>

#include "client/client_endpoint.h"
#include "client/client_impl.h"
#include "client/client_testing.h"
#include "protocol/endpoint.h"

namespace edgephys {

RelayAddress ToRelayAddress(const Endpoint& endpoint) {
  return RelayAddress{endpoint.address().to_string(), endpoint.port()};
}

Result<Endpoint> ToEndpoint(const RelayAddress& address) {
  asio::error_code error;
  const asio::ip::address ip = asio::ip::make_address(address.host, error);
  if (error) {
    return Status::InvalidArgument("relay address: not a numeric IPv4/IPv6 address: '" +
                                   address.host + "'");
  }
  return Endpoint(ip, address.port);
}

Result<RelayAddress> ParseRelayAddress(std::string_view text) {
  Result<Endpoint> endpoint = ParseEndpoint(text);
  if (!endpoint.ok()) return endpoint.status();
  return ToRelayAddress(*endpoint);
}

std::string FormatRelayAddress(const RelayAddress& address) {
  if (address.host.find(':') != std::string::npos) {
    return "[" + address.host + "]:" + std::to_string(address.port);
  }
  return address.host + ":" + std::to_string(address.port);
}

Client::Client(const ClientConfig& config, DatagramSocket* socket, ClientListener* listener)
    : impl_(std::make_unique<Impl>(config, socket, listener)) {}
Client::~Client() = default;

Status Client::Connect(const RelayAddress& server, std::span<const uint8_t> token, double now) {
  return impl_->Connect(server, token, now);
}
void Client::Update(double now) { impl_->Update(now); }
Status Client::JoinRoom(std::string_view room) { return impl_->JoinRoom(room); }
Status Client::LeaveRoom() { return impl_->LeaveRoom(); }
Result<uint32_t> Client::Spawn(const SpawnDesc& desc) { return impl_->Spawn(desc); }
Status Client::Despawn(uint32_t entity_id) { return impl_->Despawn(entity_id); }
Status Client::Grab(uint32_t entity_id, uint32_t hand_id) { return impl_->Grab(entity_id, hand_id); }
Status Client::GrabAt(uint32_t entity_id, uint32_t hand_id, const Vec3f& position,
                      const Quatf& rotation) {
  if (!impl_->joined_) return Status::NotConnected("not joined");
  if (Status st = impl_->PublishTransform(hand_id, position, rotation); !st.ok()) return st;
  const EntityState pose{hand_id, position, rotation};
  return impl_->Grab(entity_id, hand_id, &pose);
}
Status Client::Release(uint32_t entity_id) { return impl_->Release(entity_id); }
Status Client::SendMessage(MessageTarget target, uint32_t to_player,
                           std::span<const uint8_t> payload) {
  return impl_->SendMessage(target, to_player, payload);
}
Status Client::SendMessageUnreliable(MessageTarget target, uint32_t to_player,
                                     std::span<const uint8_t> payload) {
  return impl_->SendMessageUnreliable(target, to_player, payload);
}
uint64_t Client::unreliable_messages_received() const { return impl_->unreliable_.received; }
uint64_t Client::unreliable_messages_stale() const { return impl_->unreliable_.stale; }
uint64_t Client::unreliable_messages_malformed() const { return impl_->unreliable_.malformed; }
Status Client::PublishTransform(uint32_t entity_id, const Vec3f& position, const Quatf& rotation) {
  return impl_->PublishTransform(entity_id, position, rotation);
}
void Client::Disconnect() { impl_->Disconnect(); }

ClientState Client::state() const { return impl_->state_; }
bool Client::joined() const { return impl_->joined_; }
uint32_t Client::player_id() const { return impl_->player_id_; }
uint32_t Client::entity_id_base() const { return impl_->entity_id_base_; }
uint8_t Client::state_format() const { return impl_->state_format_; }
const std::string& Client::room() const { return impl_->room_; }
uint16_t Client::reject_reason() const { return impl_->reject_reason_; }
DisconnectReason Client::disconnect_reason() const { return impl_->disconnect_reason_; }
const std::string& Client::disconnect_detail() const { return impl_->disconnect_detail_; }
const ConnectionStats* Client::stats() const { return impl_->stats(); }
const std::unordered_map<uint32_t, RemoteEntity>& Client::entities() const {
  return impl_->entities_;
}
const RemoteEntity* Client::FindEntity(uint32_t id) const { return impl_->FindEntity(id); }
const std::vector<uint32_t>& Client::players() const { return impl_->players_; }
uint64_t Client::state_bytes_received() const { return impl_->bytes_state_received_; }
uint64_t Client::state_payloads_outside_room() const {
  return impl_->state_payloads_outside_room_;
}
uint64_t Client::state_payloads_refused() const {
  return impl_->state_payloads_refused_;
}
double Client::packet_arrival_unix_s() const { return impl_->packet_arrival_unix_s_; }
uint64_t Client::arrival_time_fallbacks() const { return impl_->arrival_time_fallbacks_; }
uint64_t Client::redirects_followed() const { return impl_->redirects_followed_; }
uint64_t Client::redirects_refused() const { return impl_->redirects_refused_; }
uint64_t Client::resumes() const { return impl_->resumes_; }
uint64_t Client::respawns_sent() const { return impl_->respawns_sent_; }
uint64_t Client::respawns_duplicate() const { return impl_->respawns_duplicate_; }
uint64_t Client::entities_lost() const { return impl_->entities_lost_; }
bool Client::resuming() const { return impl_->resuming_; }
RelayAddress Client::server() const { return ToRelayAddress(impl_->server_); }
uint64_t Client::packets_refused() const { return impl_->packets_refused_; }

Status ClientTesting::SendStateUnchecked(Client& client, const EntityState& state, double now) {
  return client.impl_->SendStateUnchecked(state, now);
}
void ClientTesting::DeliverUnreliable(Client& client, std::span<const uint8_t> payload) {
  client.impl_->OnUnreliablePayload(0, payload);
}
Status ProtocolPeer::SendReliable(Client& client, std::span<const uint8_t> message) {
  return client.impl_->SendReliableUnchecked(message);
}
Status ProtocolPeer::SendUnreliable(Client& client, std::span<const uint8_t> payload,
                                    double now) {
  return client.impl_->SendUnreliableRaw(payload, now);
}
void ProtocolPeer::SetControlMessageListener(Client& client, ControlMessageListener* listener) {
  client.impl_->control_listener_ = listener;
}

}  // namespace edgephys
