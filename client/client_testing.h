// Raw senders of the client, kept off the game-facing API (client/client.h): they bypass the
// SDK's checks on purpose. For tests and fuzzers that exercise the relay's authority and
// validation, and for tools that speak the protocol themselves (the PhyS worker's result and
// state streams). Games use Client::PublishTransform, Spawn, Grab, ...
//
// Thread-safety and failure modes: those of the Client (one thread; kNotConnected before the
// handshake completes; kQueueFull when the reliable window is full).
#pragma once

#include <cstdint>
#include <span>

#include "client/client.h"

namespace edgephys {

class ClientTesting {
 public:
  // Sends a state for any id, owned or not, unchecked, in its own packet now.
  static Status SendStateUnchecked(Client& client, const EntityState& state, double now) {
    return client.SendStateUnchecked(state, now);
  }
  // Sends raw bytes on the reliable channel.
  static Status SendReliableUnchecked(Client& client, std::span<const uint8_t> message) {
    return client.SendReliableUnchecked(message);
  }
  // Sends one unreliable payload now, as is.
  static Status SendUnreliableRaw(Client& client, std::span<const uint8_t> payload, double now) {
    return client.SendUnreliableRaw(payload, now);
  }
};

}  // namespace edgephys
