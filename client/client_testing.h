// Internal side of the client SDK, kept off the game-facing API (client/client.h): raw senders
// that bypass the SDK's checks on purpose, and the hook that hands tools the control messages
// the SDK does not handle itself. For tests and fuzzers that exercise the relay's authority and
// validation (production tools use client/protocol_peer.h). Games use Client::PublishTransform,
// Spawn, Grab, ...
//
// Thread-safety and failure modes: those of the Client (one thread; kNotConnected before the
// handshake completes; kQueueFull when the reliable window is full).
#pragma once

#include <cstdint>
#include <span>

#include "client/client.h"
#include "client/protocol_peer.h"

namespace edgephys {

class ClientTesting {
 public:
  // Sends a state for any id, owned or not, unchecked, in its own packet now.
  static Status SendStateUnchecked(Client& client, const EntityState& state, double now);
  // Sends raw bytes on the reliable channel (ProtocolPeer::SendReliable).
  static Status SendReliableUnchecked(Client& client, std::span<const uint8_t> message) {
    return ProtocolPeer::SendReliable(client, message);
  }
  // Sends one unreliable payload now, as is (ProtocolPeer::SendUnreliable).
  static Status SendUnreliableRaw(Client& client, std::span<const uint8_t> payload, double now) {
    return ProtocolPeer::SendUnreliable(client, payload, now);
  }
  // Hands `payload` to the client as if the relay had sent it as an unreliable payload now.
  static void DeliverUnreliable(Client& client, std::span<const uint8_t> payload);
  static void SetControlMessageListener(Client& client, ControlMessageListener* listener) {
    ProtocolPeer::SetControlMessageListener(client, listener);
  }
};

}  // namespace edgephys
