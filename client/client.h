// edgephys client SDK (the "GHost" side): connect to a relay with a join token, join a room,
// spawn entities, publish their transforms and see everyone else's.
//
// Usage (one thread; time and I/O injected, like the relay):
//
//   auto socket = edgephys::UdpSocket::Open(*edgephys::ParseEndpoint("0.0.0.0:0"));
//   edgephys::Client client(edgephys::ClientConfig{}, socket->get(), &my_listener);
//   client.Connect(relay_endpoint, token_bytes, now);
//   // every frame:
//   client.Update(now);                       // handshake, receive, resend, publish
//   if (client.state() == ClientState::kConnected && !client.joined()) client.JoinRoom("lobby");
//   auto id = client.Spawn({.position = {0, 1, 0}});        // after OnJoined
//   client.PublishTransform(*id, position, rotation);        // any time; sent at publish rate
//   for (auto& [id, e] : client.entities()) render(e.state); // or use the listener callbacks
//
// Entities: each player owns a block of kEntityIdBlock entity ids (protocol/types.h; the base
// comes with Joined). Spawn() picks the next free id in that block. Only the owner may move or
// despawn an entity; the relay drops (and counts) anything else. State reaches others on the
// unreliable channel, converging under loss: the SDK re-sends an entity's latest state until
// the relay acknowledges it.
//
// Thread-safety: none; use a Client from one thread. Listener callbacks run inside Update()
// and the public methods, on that thread; they must not call Update() re-entrantly.
// Memory: O(entities in the room). No allocation per received state in steady state.
// Cost: a received state of a known remote entity costs one hash lookup (plus one in the owned
// table only for ids in this player's own block) besides decoding and the listener call
// (bench/client_bench.cc).
// Latency: with ClientConfig::record_arrival_times each received state carries the time its
// datagram reached the host (RemoteEntity::arrival_unix_s), unaffected by how late Update() runs.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "protocol/packet_seal.h"
#include "protocol/connection.h"
#include "protocol/container_builder.h"
#include "edgephys/schema/control_generated.h"
#include "protocol/delta_codec.h"
#include "protocol/shared_delta_codec.h"
#include "protocol/datagram_socket.h"
#include "protocol/replication_tracker.h"
#include "protocol/soft_body_codec.h"
#include "protocol/state_codec.h"
#include "protocol/status.h"
#include "protocol/types.h"

namespace edgephys {

// Largest soft body (particles) a client accepts from the relay.
inline constexpr uint32_t kMaxSoftBodyNodes = 1 << 16;

struct ClientConfig {
  ConnectionConfig connection;      // keep-alive and timeout are taken from the relay's Accept
  double handshake_resend_s = 0.25; // Hello / Connect repeated this often until answered
  double handshake_timeout_s = 5.0; // give up (kFailed) after this long without Accept
  double publish_rate_hz = 30.0;    // owned entities' transforms sent at most this often
  // Record when each received datagram arrived (RemoteEntity::arrival_unix_s,
  // Client::packet_arrival_unix_s()), for latency measurements. Off by default. Connect() asks
  // the socket for arrival times (DatagramSocket::EnableArrivalTimes; a UdpSocket uses the
  // kernel's receive timestamp, so the time a datagram waited in the socket's queue before
  // Update() read it is not counted). Where the socket gives none, the time of the read is
  // used instead and counted in arrival_time_fallbacks(). Cost when on: a recvmsg(2) with a
  // control message per datagram instead of a recvfrom(2), plus a clock read per fallback.
  bool record_arrival_times = false;

  // Clusters of relays (docs/operations.md, "Scale-out and failover"). A relay that does not
  // hold the token's room answers Connect with a signed Redirect (protocol/redirect.h); the SDK
  // checks it against its token and the clock and repeats the handshake at the named relay, at
  // most this many times per handshake. Forged or expired redirects are ignored and counted
  // (redirects_refused()). 0: follow none.
  int max_redirects = 4;
  // Session continuity across a relay's death: when the connection ends by timeout or server
  // shutdown while in a room, reconnect with the same token (so the same player id), rejoin
  // the room and keep this player's entities and id block, without OnDisconnected or a second
  // OnJoined. Tried at the last relay, then the first relay and `relays` in turn, each for
  // resume_attempt_s, for at most resume_timeout_s (then kDisconnected, reason kTimeout).
  // If the room comes back with another id block, the owned entities are dropped and the game
  // gets OnJoined again.
  bool resume = false;
  std::vector<Endpoint> relays;
  double resume_attempt_s = 1.0;
  double resume_timeout_s = 15.0;
  // Refuse a relay that does not seal packets (docs/protocol.md §3a). An Accept without the
  // relay's key (a relay run with --packet-auth false, or an on-path attacker who stripped the
  // key to downgrade the session to unauthenticated packets) ends the handshake at once in
  // kRejected with reject_reason() AuthRequired, and the SDK sends the relay a Disconnect;
  // nothing is ever sent unsealed. false: such an Accept connects without packet
  // authentication (only to measure a relay run with --packet-auth false).
  bool require_packet_auth = true;
};

enum class ClientState {
  kIdle,           // nothing started
  kHandshaking,    // Hello / Connect in flight
  kConnected,      // Accept received; JoinRoom may be sent
  kRejected,       // the relay refused: see reject_reason()
  kDisconnected,   // connection ended: see disconnect_reason()
  kFailed,         // no answer within handshake_timeout_s
};

// An entity in the joined room, as this client knows it.
struct RemoteEntity {
  uint32_t id = 0;
  uint32_t owner = 0;          // player id; 0 = the room
  uint32_t parent = 0;
  uint32_t flags = 0;
  bool spawned = false;        // Spawn received (a state may arrive first)
  bool has_state = false;      // at least one state received after the spawn transform
  EntityState state;           // latest received transform
  uint32_t state_time_ms = 0;  // relay time of that state
  // When the datagram that carried `state` (or the spawn, until a state arrives) reached this
  // host: seconds since the Unix epoch, CLOCK_REALTIME. 0 unless
  // ClientConfig::record_arrival_times (see there for the fallback when the OS gives none).
  double arrival_unix_s = 0;
  std::vector<Vec3f> nodes;    // soft body particles (PhyS-simulated soft bodies)
};

// Callbacks, all optional. Called from Update() (or the call that caused them).
class ClientListener {
 public:
  virtual ~ClientListener() = default;
  virtual void OnConnected(uint32_t player_id) { (void)player_id; }
  virtual void OnRejected(uint16_t reason) { (void)reason; }
  virtual void OnDisconnected(DisconnectReason reason) { (void)reason; }
  virtual void OnJoined(std::string_view room, uint32_t entity_id_base) {
    (void)room, (void)entity_id_base;
  }
  virtual void OnPlayerJoined(uint32_t player_id) { (void)player_id; }
  virtual void OnPlayerLeft(uint32_t player_id) { (void)player_id; }
  virtual void OnEntitySpawned(const RemoteEntity& entity) { (void)entity; }
  virtual void OnEntityUpdated(const RemoteEntity& entity) { (void)entity; }
  virtual void OnEntityDespawned(uint32_t entity_id) { (void)entity_id; }
  // PhyS reported a collision, trigger, guard reset, grab or release (schema PhysicsEventKind;
  // see schema/control.fbs for what a and b are). Reliable, in step order, once each.
  virtual void OnPhysicsEvent(uint8_t kind, uint32_t entity_a, uint32_t entity_b) {
    (void)kind, (void)entity_a, (void)entity_b;
  }
  // A soft body's particles changed (entity.nodes).
  virtual void OnSoftBodyUpdated(const RemoteEntity& entity) { (void)entity; }
  // A verified control message the SDK does not handle itself (tools and the PhyS worker
  // build on this).
  virtual void OnOtherMessage(const schema::ControlMessage& message) { (void)message; }
  // The relay refused a request (RejectReason code, schema/control.fbs).
  virtual void OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) {
    (void)reason, (void)entity_id, (void)detail;
  }
};

// What Spawn() sends: an EntitySpec (protocol/container_builder.h) — the entity's transform,
// hierarchy (parent_id) and flags (schema::EntityFlags: Persistent, Offloaded, Hand, ...) and,
// the paper's dissection, its physics components. Spawn() ignores `id` and `owner`: it picks the
// id from this player's block and the owner is this player.
// With the Offloaded flag, a dynamic rigid body or a soft body is handed to PhyS: the relay
// simulates it and it becomes PhyS-owned (this client receives its state like everyone else and
// may still despawn, grab and release it). Without Offloaded, colliders and bodies are mirrored
// into PhyS as kinematic bodies that follow this client's PublishTransform(), so local physics
// pushes PhyS-owned objects.
using SpawnDesc = EntitySpec;

class Client final : private ConnectionHandler, private PacketWriter {
 public:
  // `socket` (and `listener`, if given) are not owned and must outlive the client.
  Client(const ClientConfig& config, DatagramSocket* socket, ClientListener* listener = nullptr);
  ~Client() override;
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  // Starts the handshake with the relay at `server`. `token` is the binary join token (decode
  // the printable form with Base64UrlDecode). kInvalidArgument if already started.
  Status Connect(const Endpoint& server, std::span<const uint8_t> token, double now);

  // Receives everything pending, advances the handshake, resends, publishes due transforms.
  void Update(double now);

  // Joins the room the token grants (kNotConnected before kConnected). OnJoined follows.
  Status JoinRoom(std::string_view room);
  Status LeaveRoom();

  // Spawns an entity owned by this client; returns its id. kNotConnected before OnJoined,
  // kResourceExhausted when the id block is used up, kInvalidArgument on a non-finite or
  // non-unit transform.
  Result<uint32_t> Spawn(const SpawnDesc& desc);
  // kNotFound if this client does not own `entity_id`.
  Status Despawn(uint32_t entity_id);
  // Asks PhyS to attach entity `entity_id` to this client's hand `hand_id` (the hand's trigger
  // must hover it); OnPhysicsEvent(Grabbed) or OnError(GrabRefused) follows.
  Status Grab(uint32_t entity_id, uint32_t hand_id);
  Status Release(uint32_t entity_id);
  // Records the latest transform of an owned entity; it goes out at the publish rate.
  // kNotFound if not owned, kInvalidArgument if not finite / not unit.
  Status PublishTransform(uint32_t entity_id, const Vec3f& position, const Quatf& rotation);

  // Sends a disconnect (kClientLeft) to the relay.
  void Disconnect();

  ClientState state() const { return state_; }
  bool joined() const { return joined_; }
  uint32_t player_id() const { return player_id_; }
  uint32_t entity_id_base() const { return entity_id_base_; }
  const std::string& room() const { return room_; }
  uint16_t reject_reason() const { return reject_reason_; }
  DisconnectReason disconnect_reason() const { return disconnect_reason_; }
  // The relay's text for why it is ending this connection (an operator's kick, room close or
  // drain: ControlMessage Disconnecting, docs/protocol.md), set when that message arrives,
  // before the Disconnect itself (so it is there when OnDisconnected runs). Empty otherwise.
  const std::string& disconnect_detail() const { return disconnect_detail_; }
  // nullptr before kConnected.
  const ConnectionStats* stats() const;
  // Others' entities (and own entities are not listed).
  const std::unordered_map<uint32_t, RemoteEntity>& entities() const { return entities_; }
  const RemoteEntity* FindEntity(uint32_t id) const;
  const std::vector<uint32_t>& players() const { return players_; }
  // Bytes of state payload received (all formats), for bandwidth measurements.
  uint64_t state_bytes_received() const { return bytes_state_received_; }
  // State payloads that arrived while not in a room, and were dropped. The relay sends a
  // member states only after it has acknowledged its Joined message, so in a room this stays 0;
  // late payloads from a room just left land here.
  uint64_t state_payloads_outside_room() const { return state_payloads_outside_room_; }
  // Arrival time (as RemoteEntity::arrival_unix_s: Unix seconds, CLOCK_REALTIME) of the
  // datagram Update() read last. Inside a listener callback run by Update() it is the datagram
  // that delivered what the callback reports (for a reliable message: the datagram that
  // completed it or, after a loss, the resend that let it through in order). 0 before any
  // datagram or unless ClientConfig::record_arrival_times.
  double packet_arrival_unix_s() const { return packet_arrival_unix_s_; }
  // Datagrams whose arrival time is the time of the read, because the socket gave none
  // (arrival times unsupported, e.g. a simulated network, or no timestamp from the OS). Only
  // counted with ClientConfig::record_arrival_times.
  uint64_t arrival_time_fallbacks() const { return arrival_time_fallbacks_; }
  // Cluster: signed redirects followed and refused (forged, expired, or too many); sessions
  // resumed after a relay was lost (ClientConfig::resume); whether one is under way; the relay
  // this client talks to now.
  uint64_t redirects_followed() const { return redirects_followed_; }
  uint64_t redirects_refused() const { return redirects_refused_; }
  uint64_t resumes() const { return resumes_; }
  bool resuming() const { return resuming_; }
  const Endpoint& server() const { return server_; }
  // Datagrams from the relay's address that failed authentication or were replays (dropped).
  uint64_t packets_refused() const { return packets_refused_; }

 private:
  // Raw senders (unchecked state, reliable bytes, unreliable payloads) for tests, fuzzers and
  // the PhyS worker: client/client_testing.h.
  friend class ClientTesting;
  Status SendStateUnchecked(const EntityState& state, double now);
  Status SendReliableUnchecked(std::span<const uint8_t> message);
  Status SendUnreliableRaw(std::span<const uint8_t> payload, double now);

  struct OwnedEntity {
    EntityState state;
    uint32_t version = 1;
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

  ClientConfig config_;
  DatagramSocket* socket_;
  ClientListener* listener_;
  ClientListener null_listener_;
  ClientState state_ = ClientState::kIdle;
  Endpoint server_;
  std::vector<uint8_t> token_;
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
  uint32_t next_local_id_ = 1;
  std::vector<uint32_t> players_;
  std::unordered_map<uint32_t, RemoteEntity> entities_;
  std::unordered_set<uint32_t> despawned_;  // tombstones: late states for these are ignored
  std::unordered_map<uint32_t, OwnedEntity> owned_;
  ReplicationTracker tracker_;
  double next_publish_ = 0;
  double now_ = 0;

  std::vector<uint8_t> receive_buffer_;
  std::vector<uint8_t> payload_buffer_;
  std::vector<std::pair<uint32_t, uint32_t>> sent_scratch_;
  StateBatch batch_;
  FloatStateEncoder encoder_;
  std::unique_ptr<DeltaDecoder> delta_decoder_;  // rooms using format 2
  std::unique_ptr<SharedDeltaDecoder> shared_decoder_;  // rooms using format 9
  float position_step_m_ = QuantizationConfig{}.position_step_m;  // the room's quantisation step
  SoftBodyChunk soft_chunk_;
  uint64_t bytes_state_received_ = 0;
  uint64_t state_payloads_outside_room_ = 0;
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
};

}  // namespace edgephys
