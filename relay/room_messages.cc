// RoomHost::Message: application messages from a member to the room, to the others or to one
// player, with their budgets (relay/room_host.h, docs/protocol.md "Application messages").
#include <flatbuffers/flatbuffers.h>

#include "protocol/handshake.h"
#include "protocol/join_token.h"
#include "relay/room_host.h"

namespace edgephys {

void RoomHost::Message(MemberLink& link, const schema::AppMessage& message, double now) {
  using schema::MessageTarget;
  using schema::RejectReason;
  const uint32_t sender = link.player_id();
  const auto refuse = [&](RejectReason reason, std::string_view detail) {
    ++message_stats_.refused;
    link.SendError(reason, 0, detail);
  };
  if ((link.permissions() & kPermissionMessage) == 0) {
    return refuse(RejectReason::NotPermitted, "the join token does not allow messages");
  }
  const MessageTarget target = message.target();
  if (target != MessageTarget::Room && target != MessageTarget::Others &&
      target != MessageTarget::Player) {
    return refuse(RejectReason::InvalidMessage, "unknown message target");
  }
  const size_t size = message.payload() != nullptr ? message.payload()->size() : 0;
  const RoomBudgets& budgets = room_.config().budgets;
  if (size > budgets.max_message_bytes) {
    return refuse(RejectReason::OverBudget, "message larger than the room allows");
  }
  const Member* to = nullptr;
  if (target == MessageTarget::Player) {
    auto it = room_.members().find(message.to_player());
    if (message.to_player() == 0 || it == room_.members().end()) {
      return refuse(RejectReason::UnknownPlayer, "no such player in the room");
    }
    to = &it->second;
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
  flatbuffers::FlatBufferBuilder fbb(64 + size);
  const auto payload = fbb.CreateVector(message.payload() != nullptr ? message.payload()->data()
                                                                     : nullptr,
                                        size);
  FinishControl(fbb, schema::CreateAppMessage(fbb, target, message.to_player(), sender, payload));
  const std::span<const uint8_t> out(fbb.GetBufferPointer(), fbb.GetSize());
  ++message_stats_.forwarded;
  if (to != nullptr) {
    SendToMember(message.to_player(), *to, out);
    ++message_stats_.delivered;
    return;
  }
  for (const auto& [pid, m] : room_.members()) {
    if (target == MessageTarget::Others && pid == sender) continue;
    SendToMember(pid, m, out);
    ++message_stats_.delivered;
  }
}

}  // namespace edgephys
