// RoomHost::Message and MessageUnreliable: application messages from a member to the room, to
// the others or to one player, with their budgets (relay/room_host.h, docs/protocol.md
// "Application messages").
#include <flatbuffers/flatbuffers.h>

#include <array>

#include "protocol/app_message_codec.h"
#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "relay/room_host.h"

namespace edgephys {

bool RoomHost::AdmitMessage(MemberLink& link, uint8_t target, uint32_t to_player, size_t size,
                            const Member** to, MessageRates** rates_out, double now) {
  using schema::RejectReason;
  const uint32_t sender = link.player_id();
  const auto refuse = [&](RejectReason reason, std::string_view detail) {
    ++message_stats_.refused;
    link.SendError(reason, 0, detail);
    return false;
  };
  if ((link.permissions() & kPermissionMessage) == 0) {
    return refuse(RejectReason::NotPermitted, "the join token does not allow messages");
  }
  if (target > static_cast<uint8_t>(schema::MessageTarget::Player)) {
    return refuse(RejectReason::InvalidMessage, "unknown message target");
  }
  const RoomBudgets& budgets = room_.config().budgets;
  if (size > budgets.max_message_bytes) {
    return refuse(RejectReason::OverBudget, "message larger than the room allows");
  }
  *to = nullptr;
  if (target == static_cast<uint8_t>(schema::MessageTarget::Player)) {
    auto it = room_.members().find(to_player);
    if (to_player == 0 || it == room_.members().end()) {
      return refuse(RejectReason::UnknownPlayer, "no such player in the room");
    }
    *to = &it->second;
  }
  if (!message_rates_ready_) {
    room_message_rates_ = {TokenBucket(budgets.messages_per_s, 2 * budgets.messages_per_s),
                           TokenBucket(budgets.message_bytes_per_s, 2 * budgets.message_bytes_per_s)};
    message_rates_ready_ = true;
  }
  auto [rates, fresh] = message_rates_.try_emplace(sender);
  if (fresh) {
    rates->second = {
        TokenBucket(budgets.messages_per_s_per_player, 2 * budgets.messages_per_s_per_player),
        TokenBucket(budgets.message_bytes_per_s_per_player,
                    2 * budgets.message_bytes_per_s_per_player)};
  }
  // A bucket's burst (2 s of its rate) must hold one largest message, or it could never pass.
  const double cost = static_cast<double>(size);
  if (!rates->second.count.Take(now) || !rates->second.bytes.Take(now, cost)) {
    return refuse(RejectReason::RateLimited, "too many messages from this player; slow down");
  }
  if (!room_message_rates_.count.Take(now) || !room_message_rates_.bytes.Take(now, cost)) {
    return refuse(RejectReason::RateLimited, "too many messages in this room; slow down");
  }
  *rates_out = &rates->second;
  ++message_stats_.forwarded;
  return true;
}

void RoomHost::Message(MemberLink& link, const schema::AppMessage& message, double now) {
  const uint32_t sender = link.player_id();
  const auto target = static_cast<uint8_t>(message.target());
  const size_t size = message.payload() != nullptr ? message.payload()->size() : 0;
  const Member* to = nullptr;
  MessageRates* rates = nullptr;
  if (!AdmitMessage(link, target, message.to_player(), size, &to, &rates, now)) return;
  flatbuffers::FlatBufferBuilder fbb(64 + size);
  const auto payload = fbb.CreateVector(message.payload() != nullptr ? message.payload()->data()
                                                                     : nullptr,
                                        size);
  FinishControl(fbb, schema::CreateAppMessage(fbb, message.target(), message.to_player(), sender,
                                              payload));
  const std::span<const uint8_t> out(fbb.GetBufferPointer(), fbb.GetSize());
  if (to != nullptr) {
    SendToMember(message.to_player(), *to, out);
    ++message_stats_.delivered;
    return;
  }
  for (const auto& [pid, m] : room_.members()) {
    if (message.target() == schema::MessageTarget::Others && pid == sender) continue;
    SendToMember(pid, m, out);
    ++message_stats_.delivered;
  }
}

void RoomHost::MessageUnreliable(MemberLink& link, std::span<const uint8_t> payload, double now) {
  AppMessageHeader h;
  std::span<const uint8_t> body;
  if (!DecodeAppMessage(payload, &h, &body)) {
    ++message_stats_.refused;
    return link.DropPayload(DropReason::kMalformed);
  }
  const uint32_t sender = link.player_id();
  const Member* to = nullptr;
  MessageRates* rates = nullptr;
  if (!AdmitMessage(link, h.target, h.to_player, body.size(), &to, &rates, now)) return;
  ++message_stats_.unreliable;
  h.sender = sender;
  h.sequence = ++rates->unreliable_sequence;
  if (h.target != static_cast<uint8_t>(schema::MessageTarget::Player)) h.to_player = 0;
  std::array<uint8_t, kMaxUnreliablePayload> buffer;
  const size_t n = EncodeAppMessage(h, body, buffer);
  const std::span<const uint8_t> out(buffer.data(), n);
  if (to != nullptr) {
    if (to->link->SendUnreliable(out, now)) ++message_stats_.delivered;
    return;
  }
  const bool others = h.target == static_cast<uint8_t>(schema::MessageTarget::Others);
  for (const auto& [pid, m] : room_.members()) {
    if (others && pid == sender) continue;
    if (m.link->SendUnreliable(out, now)) ++message_stats_.delivered;
  }
}

}  // namespace edgephys
