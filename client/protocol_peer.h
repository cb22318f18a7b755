// ProtocolPeer: the Client's raw channel for programs that speak parts of the protocol
// themselves (the PhyS worker's Worker* messages, result and state streams). Kept off the
// game-facing API (client/client.h): these calls bypass the SDK's own checks, so the caller
// builds and verifies what it sends.
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

class ProtocolPeer {
 public:
  // Sends `message` (a complete control message) on the reliable channel, as is.
  static Status SendReliable(Client& client, std::span<const uint8_t> message);
  // Sends one unreliable payload now, as is.
  static Status SendUnreliable(Client& client, std::span<const uint8_t> payload, double now);
  // Routes the control messages the Client does not handle to `listener` (not owned; must
  // outlive the client or be replaced first); nullptr: they are dropped (the default).
  static void SetControlMessageListener(Client& client, ControlMessageListener* listener);
};

}  // namespace edgephys
