// Client::Impl: the client SDK's state and protocol work behind the pointer of
// client/client.h. Internal to client/: client.cc holds the protocol work, client_public.cc the
// public forwarders, the address conversions and ClientTesting. Contracts are Client's.
#pragma once

#include <map>
#include <memory>
#include <span>
#include <string>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "client/client.h"
#include "client/client_testing.h"
#include "edgephys/schema/control_generated.h"
#include "protocol/connection.h"
#include "protocol/datagram_socket.h"
#include "protocol/handshake.h"
#include "protocol/packet_seal.h"
#include "protocol/replication_tracker.h"
#include "protocol/soft_delta_stream.h"
#include "protocol/state_codec.h"
#include "protocol/state_formats.h"

namespace edgephys {

// The client's state and protocol work. Client forwards to it; the per-state path
// (OnUnreliablePayload) runs entirely inside it, so the pointer costs one indirection per
// public call, none per received state.
class Client::Impl final : private ConnectionHandler, private PacketWriter {
 public:
  Impl(const ClientConfig& config, DatagramSocket* socket, ClientListener* listener);

  Status Connect(const RelayAddress& server, std::span<const uint8_t> token, double now);
  void Update(double now);
  Status JoinRoom(std::string_view room);
  Status LeaveRoom();
  Result<uint32_t> Spawn(const SpawnDesc& desc);
  Status Despawn(uint32_t entity_id);
  Status Grab(uint32_t entity_id, uint32_t hand_id, const EntityState* hand_pose = nullptr);
  Status Release(uint32_t entity_id);
  Status SendMessage(MessageTarget target, uint32_t to_player, std::span<const uint8_t> payload);
  // Unreliable messages (client/client_messages.cc): send, and a format-15 payload received.
  Status SendMessageUnreliable(MessageTarget target, uint32_t to_player,
                               std::span<const uint8_t> payload);
  void OnUnreliableMessage(std::span<const uint8_t> payload);
  Status PublishTransform(uint32_t entity_id, const Vec3f& position, const Quatf& rotation);
  // Properties (client/client_properties.cc).
  Result<uint32_t> WriteProperty(uint32_t entity_id, std::string_view key,
                                 const PropertyValue& value, PropertyAuthority authority,
                                 bool check_version, uint32_t expected_version);
  void OnPropertyMessage(const schema::ControlMessage& msg);
  void ForgetEntityProperties(uint32_t entity_id);
  // Ownership (client/client_ownership.cc).
  Status RequestOwnership(uint32_t entity_id);
  Status HandOver(uint32_t entity_id, uint32_t player_id);
  Status ReleaseOwnership(uint32_t entity_id, const Vec3f& linear, const Vec3f& angular);
  Status SetTakeoverAllowed(uint32_t entity_id, bool allowed);
  uint32_t OwnerOf(uint32_t entity_id) const;
  Status SetOwnerLeave(uint32_t entity_id, uint8_t choice);
  Status SendOwnership(uint32_t entity_id, uint8_t action, uint32_t to_player,
                       bool takeover_allowed, const Vec3f& linear = {},
                       const Vec3f& angular = {}, uint8_t on_owner_leave = 0);
  void OnOwnershipChanged(const schema::OwnershipChanged& change);
  void Disconnect();
  const ConnectionStats* stats() const;
  const RemoteEntity* FindEntity(uint32_t id) const;

  Status SendStateUnchecked(const EntityState& state, double now);
  Status SendReliableUnchecked(std::span<const uint8_t> message);
  Status SendUnreliableRaw(std::span<const uint8_t> payload, double now);

  struct OwnedEntity {
    EntityState state;
    uint32_t version = 1;
    // As its Spawn said (kept for when the entity is handed to another player).
    uint32_t parent = 0;
    uint32_t flags = 0;
    uint32_t authority_seq = 0;    // of the latest ownership change known
    bool takeover_allowed = false;
    // Velocities it had when this client gained it from PhyS (OwnedMotion); 0 otherwise.
    Vec3f linear_velocity, angular_velocity;
    // The ControlMessage{Spawn} this client sent for it (empty for an entity gained from
    // another player or PhyS): sent again after a resume (RespawnAfterResume).
    std::vector<uint8_t> spawn;
  };
  void OnReliableMessage(std::span<const uint8_t> message) override;
  void OnUnreliablePayload(uint16_t sequence, std::span<const uint8_t> payload) override;
  void OnPacketAcked(uint16_t sequence) override;
  void WritePacket(std::span<const uint8_t> packet) override;
  Status DecodeStates(std::span<const uint8_t> payload);
  void HandleHandshakePacket(std::span<const uint8_t> packet, double now);
  void SendHandshake(double now);
  void Publish(double now);
  void ResetRoom();
  // Cluster: follows a Redirect datagram (checked against the token); starts/advances resume.
  void HandleRedirect(const schema::ControlMessage& msg, double now);
  void RestartHandshake(const Endpoint& server, double now);
  void StartResume(double now);
  // After a resumed Joined: sends the stored Spawn of every owned entity of this player's id
  // block again (at its current pose), in id order, and remembers them in respawned_. The
  // relay answers a re-spawn the restored room already holds with Error{DuplicateEntity}
  // (swallowed: the entity is there) and one it refuses otherwise with another Error (the
  // entity is dropped from owned_ and reported lost: RespawnRefused).
  void RespawnAfterResume();
  // true if `error` answered a re-spawn (and was handled here; the game saw it if it was a loss).
  bool RespawnRefused(uint16_t reason, uint32_t entity_id, std::string_view detail);
  // An accepted re-spawn gets no answer: once the relay has acknowledged every re-spawn and
  // kRespawnAnswerS (or 4 round trips, if longer) has passed for its answers to arrive,
  // respawned_ is cleared, so that later errors about those entities reach the game as such.
  void ExpireRespawns(double now);
  // Drops owned entity `id` and tells the game it is gone: OnError(reason, id, "lost in
  // failover: <why>").
  void ReportLost(uint16_t reason, uint32_t id, std::string_view why);

  ClientConfig config_;
  std::vector<Endpoint> relays_;  // config_.relays, parsed by Connect()
  DatagramSocket* socket_;
  ClientListener* listener_;
  ClientListener null_listener_;
  ControlMessageListener* control_listener_ = nullptr;  // ProtocolPeer
  ClientState state_ = ClientState::kIdle;
  Endpoint server_;
  std::vector<uint8_t> token_;     // the client token's relay part (sent in Connect)
  SessionSecret session_secret_{};  // the client token's secret part (never sent)
  HandshakeProof connect_proof_{};  // the proof of the last Connect sent (Accept chains to it)
  std::vector<uint8_t> cookie_;
  uint64_t nonce_ = 0;
  double handshake_started_ = 0;
  double last_handshake_send_ = -1e9;
  std::unique_ptr<Connection> connection_;
  // Packet authentication (protocol/packet_seal.h): this connection's key pair until Accept,
  // then the seal every packet goes through (null if the relay does not seal).
  std::unique_ptr<KeyExchange> key_exchange_;
  std::unique_ptr<PacketSeal> seal_;
  std::vector<uint8_t> seal_buffer_, open_buffer_;
  uint64_t packets_refused_ = 0;
  uint32_t player_id_ = 0;
  uint16_t reject_reason_ = 0;
  DisconnectReason disconnect_reason_ = DisconnectReason::kNone;
  std::string disconnect_detail_;

  bool joined_ = false;
  std::string room_;
  uint32_t entity_id_base_ = 0;
  uint8_t state_format_ = 0;  // the joined room's (Joined.state_format); 0 before a Joined
  uint32_t next_local_id_ = 1;
  std::vector<uint32_t> players_;
  std::unordered_map<uint32_t, RemoteEntity> entities_;
  std::unordered_set<uint32_t> despawned_;  // tombstones: late states for these are ignored
  std::unordered_map<uint32_t, OwnedEntity> owned_;
  std::map<PropertyKey, PropertyRecord> properties_;
  uint32_t last_property_request_ = 0;
  // Unreliable messages: the newest sequence delivered per sender (this room; cleared by
  // ResetRoom) and what was received and dropped.
  struct UnreliableMessages {
    std::unordered_map<uint32_t, uint32_t> last;
    uint32_t sent = 0;  // this connection's last message number (reset with the connection)
    uint64_t received = 0, stale = 0, malformed = 0;
  } unreliable_;
  ReplicationTracker tracker_;
  double next_publish_ = 0;
  double now_ = 0;

  std::vector<uint8_t> receive_buffer_;
  std::vector<uint8_t> payload_buffer_;
  std::vector<std::pair<uint32_t, uint32_t>> sent_scratch_;
  StateBatch batch_;
  FloatStateEncoder encoder_;
  // The decoder of the room's state format (protocol/state_formats.h); per room (reset on
  // Joined); nullptr: the SDK does not decode the room's format.
  std::unique_ptr<StateDecoder> decoder_;
  float position_step_m_ = QuantizationConfig{}.position_step_m;  // the room's quantisation step
  std::unique_ptr<SoftDeltaReceiver> soft_decoder_;  // format 11; per room (reset on Joined)
  uint64_t bytes_state_received_ = 0;
  uint64_t state_payloads_outside_room_ = 0;
  uint64_t state_payloads_refused_ = 0;
  double packet_arrival_unix_s_ = 0;
  uint64_t arrival_time_fallbacks_ = 0;
  // Cluster.
  Endpoint entry_server_;  // the relay Connect() was given
  Endpoint lost_server_;   // the relay whose connection ended (resume tries it first only)
  int redirects_this_handshake_ = 0;
  uint64_t redirects_followed_ = 0;
  uint64_t redirects_refused_ = 0;
  bool resuming_ = false;
  std::string resume_room_;
  uint32_t resume_base_ = 0;
  double resume_started_ = 0;
  size_t resume_index_ = 0;
  uint64_t resumes_ = 0;
  // Resume re-spawns awaiting the relay's answer (an Error, or none when it was accepted);
  // cleared when a room is left or joined afresh.
  std::unordered_set<uint32_t> respawned_;
  uint64_t respawn_end_ = 0;        // reliable stream position after the last re-spawn
  double respawn_answers_by_ = 0;   // when respawned_ is cleared (0: not acknowledged yet)
  uint64_t respawns_sent_ = 0;       // re-spawns sent after resumes
  uint64_t respawns_duplicate_ = 0;  // ... that the restored room already held
  uint64_t entities_lost_ = 0;       // owned entities reported lost after a resume
};

}  // namespace edgephys
