// Minimal Connection collaborators for tests and benchmarks that script one side of a
// connection by hand (a fake relay in front of a Client): a PacketWriter that keeps every
// packet, and a ConnectionHandler that ignores what it is given. No test framework needed.
// Thread-safety: none.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "protocol/connection.h"

namespace edgephys::testing {

// Keeps a copy of every packet written, in order.
class CapturingWriter final : public PacketWriter {
 public:
  void WritePacket(std::span<const uint8_t> packet) override {
    packets.emplace_back(packet.begin(), packet.end());
  }
  std::vector<std::vector<uint8_t>> packets;
};

// Accepts and discards everything a Connection delivers.
class NullHandler final : public ConnectionHandler {
 public:
  void OnReliableMessage(std::span<const uint8_t>) override {}
  void OnUnreliablePayload(uint16_t, std::span<const uint8_t>) override {}
};

}  // namespace edgephys::testing
