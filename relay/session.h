// Session: one admitted client on the relay: its connection, identity (from the join token),
// room membership and what it has acknowledged of the room's state. Owned by the Relay and
// used only on its thread.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

#include "protocol/connection.h"
#include "protocol/datagram_socket.h"
#include "protocol/state_codec.h"
#include "relay/physics_link.h"
#include "relay/rate_limit.h"
#include "relay/relay_config.h"
#include "relay/replication.h"

namespace edgephys {

class Relay;

class Session final : public ConnectionHandler, public PacketWriter, public WorkerChannel {
 public:
  Session(Relay* relay, const Endpoint& endpoint, uint32_t connection_id, uint32_t player_id,
          uint32_t permissions, std::string token_room, uint64_t token_nonce,
          const ConnectionConfig& config, const AbuseLimits& limits, double now);

  // ConnectionHandler: messages from the client.
  void OnReliableMessage(std::span<const uint8_t> message) override;
  void OnUnreliablePayload(uint16_t sequence, std::span<const uint8_t> payload) override;
  void OnPacketAcked(uint16_t sequence) override;
  // PacketWriter: packets to the client.
  void WritePacket(std::span<const uint8_t> packet) override;
  // WorkerChannel: when this session is a PhyS worker.
  bool SendToWorker(std::span<const uint8_t> message) override {
    return connection_.SendReliable(message).ok();
  }
  bool WorkerConnected() const override { return connection_.connected(); }
  // While buffering (the parallel replication tick), packets are queued instead of sent;
  // FlushOutbox() sends them from the relay's thread.
  void set_buffering(bool on) { buffering_ = on; }
  void FlushOutbox();
  bool is_worker() const { return is_worker_; }
  // Rate limits (AbuseLimits); workers are exempt from the packet limits.
  bool AllowPacket(double now, size_t bytes) {
    return is_worker_ || (packets_.Take(now) && bytes_.Take(now, static_cast<double>(bytes)));
  }
  bool AllowSpawn(double now) { return spawns_.Take(now); }
  double connected_at() const { return connected_at_; }
  void set_worker(bool worker) { is_worker_ = worker; }

  Connection& connection() { return connection_; }
  const Endpoint& endpoint() const { return endpoint_; }
  uint32_t player_id() const { return player_id_; }
  uint32_t permissions() const { return permissions_; }
  const std::string& token_room() const { return token_room_; }
  uint64_t token_nonce() const { return token_nonce_; }
  // The room joined, empty if none.
  const std::string& room() const { return room_; }
  void set_room(std::string room) { room_ = std::move(room); }
  // What this client has of the joined room's state; reset on every join.
  ClientReplicator& replicator() { return *replicator_; }
  const ClientReplicator& replicator() const { return *replicator_; }
  // States are sent to a member only once it has acknowledged its Joined message (reliable
  // stream position `end`): before that, a reordered state payload could reach the client
  // before Joined, where it cannot be decoded, although the connection acknowledges it, and
  // the delta encoder would then reference a baseline the client never had.
  void HoldStatesUntilReliable(uint64_t end) { states_after_reliable_ = end; }
  bool ReadyForStates() const { return connection_.reliable_acked_end() >= states_after_reliable_; }
  void ResetReplicator(const ReplicationConfig& config) {
    replicator_ = std::make_unique<ClientReplicator>(config);
  }
  // Accept datagram re-sent when the client repeats its Connect (the first was lost).
  std::vector<uint8_t>& accept_packet() { return accept_packet_; }
  // States that arrived for the player's own, not yet spawned entities (the spawn is on the
  // reliable channel and may arrive later). Bounded; applied when the spawn arrives.
  std::unordered_map<uint32_t, EntityState>& early_states() { return early_states_; }
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
  uint64_t states_after_reliable_ = 0;
  std::string room_;
  std::unique_ptr<ClientReplicator> replicator_;
  std::vector<uint8_t> accept_packet_;
  std::unordered_map<uint32_t, EntityState> early_states_;
  bool is_worker_ = false;
  bool buffering_ = false;
  std::vector<std::vector<uint8_t>> outbox_;  // capacity reused between ticks
  size_t outbox_size_ = 0;
  double now_;
  TokenBucket packets_, bytes_, spawns_;
  double connected_at_;
};

}  // namespace edgephys
