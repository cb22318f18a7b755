// Client::SendMessage and SendMessageUnreliable: application messages to the room, and the
// unreliable ones received (client/client.h, docs/protocol.md "Application messages").
#include <flatbuffers/flatbuffers.h>

#include <array>

#include "client/client_impl.h"
#include "protocol/app_message_codec.h"
#include "protocol/handshake.h"

namespace edgephys {

static_assert(kMaxUnreliableMessageBytes == kMaxUnreliableMessagePayload);

namespace {

// SendMessage's and SendMessageUnreliable's shared checks, in order: joined, the payload's size
// (`too_large` when `oversized`), the target; `*to_player` is zeroed unless the target is a
// player.
Status CheckMessage(bool joined, bool oversized, const Status& too_large, MessageTarget target,
                    uint32_t* to_player) {
  if (!joined) return Status::NotConnected("not joined");
  if (oversized) return too_large;
  if (target != MessageTarget::kRoom && target != MessageTarget::kOthers &&
      target != MessageTarget::kPlayer) {
    return Status::InvalidArgument("unknown message target");
  }
  if (target == MessageTarget::kPlayer && *to_player == 0) {
    return Status::InvalidArgument("a message to a player needs the player's id");
  }
  if (target != MessageTarget::kPlayer) *to_player = 0;
  return Status::Ok();
}

}  // namespace

Status Client::Impl::SendMessage(MessageTarget target, uint32_t to_player,
                                 std::span<const uint8_t> payload) {
  const Status s = CheckMessage(state_ == ClientState::kConnected && joined_,
                                payload.size() > kMaxMessagePayload,
                                Status::InvalidArgument("message payload over 65536 bytes"),
                                target, &to_player);
  if (!s.ok()) return s;
  flatbuffers::FlatBufferBuilder fbb(64 + payload.size());
  const auto bytes = fbb.CreateVector(payload.data(), payload.size());
  FinishControl(fbb, schema::CreateAppMessage(fbb, static_cast<schema::MessageTarget>(target),
                                              to_player, 0, bytes));
  return connection_->SendReliable({fbb.GetBufferPointer(), fbb.GetSize()});
}

Status Client::Impl::SendMessageUnreliable(MessageTarget target, uint32_t to_player,
                                           std::span<const uint8_t> payload) {
  const Status s = CheckMessage(
      state_ == ClientState::kConnected && joined_, payload.size() > kMaxUnreliableMessagePayload,
      Status::TooLarge("unreliable message payload over 1165 bytes (one datagram)"), target,
      &to_player);
  if (!s.ok()) return s;
  AppMessageHeader h;
  h.target = static_cast<uint8_t>(target);
  h.to_player = to_player;
  h.sequence = unreliable_.sent + 1;
  std::array<uint8_t, kMaxUnreliablePayload> buffer;
  const size_t n = EncodeAppMessage(h, payload, buffer);
  Result<uint16_t> sent = connection_->SendUnreliable({buffer.data(), n}, now_, *this);
  if (!sent.ok()) return sent.status();
  ++unreliable_.sent;
  return Status::Ok();
}

void Client::Impl::OnUnreliableMessage(std::span<const uint8_t> payload) {
  AppMessageHeader h;
  std::span<const uint8_t> body;
  if (!DecodeAppMessage(payload, &h, &body) || h.sender == 0 ||
      h.target > static_cast<uint8_t>(MessageTarget::kPlayer)) {
    ++unreliable_.malformed;
    return;
  }
  auto [last, fresh] = unreliable_.last.try_emplace(h.sender, h.sequence);
  if (!fresh) {
    if (!AppSequenceNewer(h.sequence, last->second)) {
      ++unreliable_.stale;  // a duplicate, or older than one delivered already
      return;
    }
    last->second = h.sequence;
  }
  ++unreliable_.received;
  listener_->OnUnreliableMessage(h.sender, body);
}

}  // namespace edgephys
