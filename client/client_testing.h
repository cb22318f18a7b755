// Internal side of the client SDK, kept off the game-facing API (client/client.h): raw senders
// that bypass the SDK's checks on purpose, and the hook that hands tools the control messages
// the SDK does not handle itself. For tests and fuzzers that exercise the relay's authority and
// validation, and for tools that speak the protocol themselves (the PhyS worker's Worker*
// messages, result and state streams). Games use Client::PublishTransform, Spawn, Grab, ...
//
// Thread-safety and failure modes: those of the Client (one thread; kNotConnected before the
// handshake completes; kQueueFull when the reliable window is full).
#pragma once

#include <cstdint>
#include <span>

#include "client/client.h"

namespace edgephys {

namespace schema {
struct ControlMessage;  // edgephys/schema/control_generated.h
}  // namespace schema

// Receives the verified control messages of the reliable channel that the Client does not
// handle itself (e.g. WorkerAssign), in order, from inside Client::Update() on its thread.
// `message` is valid only during the call.
class ControlMessageListener {
 public:
  virtual ~ControlMessageListener() = default;
  virtual void OnOtherMessage(const schema::ControlMessage& message) = 0;
};

class ClientTesting {
 public:
  // Sends a state for any id, owned or not, unchecked, in its own packet now.
  static Status SendStateUnchecked(Client& client, const EntityState& state, double now);
  // Sends raw bytes on the reliable channel.
  static Status SendReliableUnchecked(Client& client, std::span<const uint8_t> message);
  // Sends one unreliable payload now, as is.
  static Status SendUnreliableRaw(Client& client, std::span<const uint8_t> payload, double now);
  // Routes the control messages the Client does not handle to `listener` (not owned; must
  // outlive the client or be replaced first); nullptr: they are dropped (the default).
  static void SetControlMessageListener(Client& client, ControlMessageListener* listener);
};

}  // namespace edgephys
