// Client::SendMessage: application messages to the room (client/client.h,
// docs/protocol.md "Application messages").
#include <flatbuffers/flatbuffers.h>

#include "client/client_impl.h"
#include "protocol/handshake.h"

namespace edgephys {

Status Client::Impl::SendMessage(MessageTarget target, uint32_t to_player,
                                 std::span<const uint8_t> payload) {
  if (state_ != ClientState::kConnected || !joined_) return Status::NotConnected("not joined");
  if (payload.size() > kMaxMessagePayload) {
    return Status::InvalidArgument("message payload over 65536 bytes");
  }
  if (target != MessageTarget::kRoom && target != MessageTarget::kOthers &&
      target != MessageTarget::kPlayer) {
    return Status::InvalidArgument("unknown message target");
  }
  if (target == MessageTarget::kPlayer && to_player == 0) {
    return Status::InvalidArgument("a message to a player needs the player's id");
  }
  if (target != MessageTarget::kPlayer) to_player = 0;
  flatbuffers::FlatBufferBuilder fbb(64 + payload.size());
  const auto bytes = fbb.CreateVector(payload.data(), payload.size());
  FinishControl(fbb, schema::CreateAppMessage(fbb, static_cast<schema::MessageTarget>(target),
                                              to_player, 0, bytes));
  return connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

}  // namespace edgephys
