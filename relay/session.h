// Session: one admitted client on the relay: its connection, identity (from the join token),
// room membership and what it has acknowledged of the room's state. Owned by the Relay and
// used only on its thread.
#pragma once

#include <cstdint>
#include <string>

#include "protocol/connection.h"
#include "protocol/datagram_socket.h"
#include "protocol/replication_tracker.h"

namespace edgephys {

class Relay;

class Session final : public ConnectionHandler, public PacketWriter {
 public:
  Session(Relay* relay, const Endpoint& endpoint, uint32_t connection_id, uint32_t player_id,
          uint32_t permissions, std::string token_room, uint64_t token_nonce,
          const ConnectionConfig& config, double now);

  // ConnectionHandler: messages from the client.
  void OnReliableMessage(std::span<const uint8_t> message) override;
  void OnUnreliablePayload(uint16_t sequence, std::span<const uint8_t> payload) override;
  void OnPacketAcked(uint16_t sequence) override;
  // PacketWriter: packets to the client.
  void WritePacket(std::span<const uint8_t> packet) override;

  Connection& connection() { return connection_; }
  const Endpoint& endpoint() const { return endpoint_; }
  uint32_t player_id() const { return player_id_; }
  uint32_t permissions() const { return permissions_; }
  const std::string& token_room() const { return token_room_; }
  uint64_t token_nonce() const { return token_nonce_; }
  // The room joined, empty if none.
  const std::string& room() const { return room_; }
  void set_room(std::string room) { room_ = std::move(room); }
  ReplicationTracker& tracker() { return tracker_; }
  void ResetTracker() { tracker_ = ReplicationTracker(); }
  // Accept datagram re-sent when the client repeats its Connect (the first was lost).
  std::vector<uint8_t>& accept_packet() { return accept_packet_; }
  double now() const { return now_; }
  void set_now(double now) { now_ = now; }

 private:
  Relay* relay_;
  Endpoint endpoint_;
  Connection connection_;
  uint32_t player_id_;
  uint32_t permissions_;
  std::string token_room_;
  uint64_t token_nonce_;
  std::string room_;
  ReplicationTracker tracker_;
  std::vector<uint8_t> accept_packet_;
  double now_;
};

}  // namespace edgephys
