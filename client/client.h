// edgephys client SDK (the "GHost" side): connect to a relay with a join token, join a room,
// spawn entities, publish their transforms and see everyone else's.
//
// Usage (one thread; time and I/O injected, like the relay):
//
//   // protocol/udp_socket.h and protocol/endpoint.h (Asio; not included by this header):
//   auto socket = edgephys::UdpSocket::Open(*edgephys::ParseEndpoint("0.0.0.0:0"));
//   edgephys::Client client(edgephys::ClientConfig{}, socket->get(), &my_listener);
//   client.Connect(*edgephys::ParseRelayAddress("127.0.0.1:7777"), token_bytes, now);
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
// Failure: calls return Status / Result (protocol/status.h) with the codes named at each
// method; errors are returned, not thrown. Network trouble shows in state() and the listener.
// Memory: O(entities in the room). No allocation per received state in steady state.
// Cost: a received state of a known remote entity costs one hash lookup (plus one in the owned
// table only for ids in this player's own block) besides decoding and the listener call
// (bench/client_bench.cc).
// Latency: with ClientConfig::record_arrival_times each received state carries the time its
// datagram reached the host (RemoteEntity::arrival_unix_s), unaffected by how late Update() runs.
//
// Dependencies: this header includes neither Asio nor FlatBuffers (nor any generated schema
// header) nor the codecs: the client's state lives behind a pointer (Client::Impl, client.cc),
// addresses are RelayAddress values, entity specs are the plain structs of
// protocol/entity_spec.h. The socket is the one seam that needs Asio (DatagramSocket,
// protocol/datagram_socket.h, only declared here); client/client_endpoint.h converts between
// RelayAddress and its Endpoint. Test-only senders and the raw control-message hook of tools
// (the PhyS worker) are in client/client_testing.h. tests/public_header_test.sh checks this.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <span>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "protocol/connection_types.h"
#include "protocol/entity_spec.h"
#include "protocol/property_value.h"
#include "protocol/status.h"
#include "protocol/types.h"

namespace edgephys {

class StateDecoderPlugin;  // client/state_decoder_plugin.h

class DatagramSocket;  // protocol/datagram_socket.h

// A relay's UDP address: a numeric IPv4 or IPv6 address (no name lookup) and a port.
// Equal addresses compare equal as written: use ParseRelayAddress or client_endpoint.h's
// ToRelayAddress for a canonical host text.
struct RelayAddress {
  std::string host;  // "127.0.0.1", "::1"
  uint16_t port = 0;
  bool operator==(const RelayAddress&) const = default;
};

// Parses "a.b.c.d:port" or "[v6]:port" into a canonical RelayAddress; kInvalidArgument on
// anything else (names, missing or out-of-range port).
Result<RelayAddress> ParseRelayAddress(std::string_view text);
// "a.b.c.d:port" or "[v6]:port".
std::string FormatRelayAddress(const RelayAddress& address);

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
  // Load generators and tests only: a decoder for state formats the SDK does not carry
  // (client/state_decoder_plugin.h: the benchmark emulations). Null: payloads of such formats
  // are refused and counted (state_payloads_refused()).
  std::shared_ptr<const StateDecoderPlugin> state_decoder;
  // Load generators only: false receives state datagrams (unreliable channel: rigid and soft
  // bodies) without decoding them. The connection still acknowledges every packet as it
  // arrives, so the relay does for this client exactly what it does for a decoding one; the
  // client just holds no states (entities() keep their spawn transforms, OnEntityUpdated and
  // OnSoftBodyUpdated are never called). Their bytes still count in state_bytes_received().
  // Reliable messages (spawns, despawns, events) are handled as usual.
  bool decode_states = true;

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
  // After the resume, the Spawn of every entity this player spawned and still owns is sent
  // again (at its latest transform): the restored room comes from the last snapshot the lost
  // relay wrote, so spawns made after it (or queued into the dead connection before the SDK
  // noticed) are not in it. Those the room holds already are not duplicated; one the relay
  // refuses (budget, rate, a parent that is gone) is dropped from the owned set and reported
  // with OnError(the relay's reason, its id, "lost in failover: ..."). If the room comes back
  // with another id block, every owned entity is reported the same way (reason NotOwner), then
  // dropped, and the game gets OnJoined again. While resuming (resuming()), Spawn() fails with
  // kNotConnected.
  // Not covered: a despawn sent into the dead connection (the restored room may still hold the
  // entity), and entities spawned with PhyS authority (not owned by this client).
  bool resume = false;
  std::vector<RelayAddress> relays;  // Connect() fails with kInvalidArgument on a bad one
  double resume_attempt_s = 1.0;
  double resume_timeout_s = 15.0;
  // Refuse a relay that does not seal packets (docs/protocol.md §3a). An Accept without the
  // relay's key (a relay run with --packet-auth false, or an on-path attacker who stripped the
  // key to downgrade the session to unauthenticated packets) ends the handshake at once in
  // kRejected with reject_reason() AuthRequired, and the SDK sends the relay a Disconnect;
  // nothing is ever sent unsealed. An Accept without the relay's proof of the session secret
  // ends it likewise with BadProof (docs/protocol.md §2 "Proofs"). false: such an Accept
  // connects without packet authentication and without a proof (only to measure a relay run
  // with --packet-auth false); a proof that is present is still checked.
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
  // Ownership: the authority sequence of the latest ownership change this client knows (0:
  // none since the spawn), and whether its owner lets others take it (RequestOwnership).
  uint32_t authority_seq = 0;
  bool takeover_allowed = false;
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
  // Another player joined the room; also once per member already there when this client joins.
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
  // The relay refused a request (RejectReason code, schema/control.fbs). Also: an owned entity
  // lost in a failover (ClientConfig::resume): `entity_id` names it, `detail` starts with "lost
  // in failover: " and says why; the entity is no longer owned (OwnerOf is no longer this
  // player).
  virtual void OnError(uint16_t reason, uint32_t entity_id, std::string_view detail) {
    (void)reason, (void)entity_id, (void)detail;
  }
  // An application message (SendMessage) from player `sender` of the room, once, in the order
  // that player sent it. `payload` is valid during the call only.
  virtual void OnMessage(uint32_t sender, std::span<const uint8_t> payload) {
    (void)sender, (void)payload;
  }
  // An unreliable application message (SendMessageUnreliable) from player `sender`: at most
  // once, never older than one already delivered from that sender (those are dropped and
  // counted, Client::unreliable_messages_stale()); some may be lost. By default it is handed
  // to OnMessage. `payload` is valid during the call only.
  virtual void OnUnreliableMessage(uint32_t sender, std::span<const uint8_t> payload) {
    OnMessage(sender, payload);
  }
  // A property of the room (entity_id 0) or of an entity changed: `property` is it now, with
  // the player who wrote it, its new version and (for this client's own writes) the request id
  // SetProperty returned. Also called, once per property, for the properties a room holds when
  // this client joins (after the spawns of their entities). In the order the relay accepted
  // the writes. Valid during the call only.
  virtual void OnPropertyChanged(const PropertyRecord& property) { (void)property; }
  // This client's compare-and-set `current.request_id` lost: `current` is the property as it
  // is now (version 0 and type kNone when it does not exist). Its PropertyChanged arrived
  // before, so properties() already holds it.
  virtual void OnPropertyConflict(const PropertyRecord& current) { (void)current; }
  // Entity `entity_id` changed owner: `new_owner` is the player who owns it now (0: the room;
  // this client's player_id(): it is this client's to publish from now on, and entities() no
  // longer lists it; another player: this client no longer publishes it, and it is listed in
  // entities() with its last published state). `authority_seq` rises by one per change of owner.
  // Also called, once per such entity, for the changes a room made before this client joined
  // (after the entity's spawn, whose owner is the current one already). In the order the relay
  // made the changes; only for entities this client knows.
  virtual void OnOwnershipChanged(uint32_t entity_id, uint32_t new_owner, uint32_t authority_seq) {
    (void)entity_id, (void)new_owner, (void)authority_seq;
  }
};

// A property's place: (entity id, 0 for the room; key).
using PropertyKey = std::pair<uint32_t, std::string>;

// Whom an application message is for (schema MessageTarget).
enum class MessageTarget : uint8_t {
  kRoom = 0,    // every member, the sender included
  kOthers = 1,  // every member but the sender
  kPlayer = 2,  // one member
};
// Largest application message payload (bytes); the room's budget may allow less.
inline constexpr size_t kMaxMessagePayload = 64 * 1024;
// Largest unreliable application message payload (bytes): one datagram less its headers
// (protocol/app_message_codec.h kMaxUnreliableMessagePayload).
inline constexpr size_t kMaxUnreliableMessageBytes = 1165;

// What Spawn() sends: an EntitySpec (protocol/entity_spec.h) — the entity's transform,
// hierarchy (parent_id) and flags (entity_flags::kPersistent, kOffloaded, kHand, ...) and,
// Decoupled Edge Physics' dissection, its physics components. Spawn() ignores `id` and
// `owner`: it picks the id from this player's block and the owner is this player.
// With the Offloaded flag, a dynamic rigid body or a soft body is handed to PhyS: the relay
// simulates it and it becomes PhyS-owned (this client receives its state like everyone else and
// may still despawn, grab and release it). Without Offloaded, colliders and bodies are mirrored
// into PhyS as kinematic bodies that follow this client's PublishTransform(), so local physics
// pushes PhyS-owned objects.
using SpawnDesc = EntitySpec;

class Client final {
 public:
  // `socket` (and `listener`, if given) are not owned and must outlive the client; the socket
  // is first used by Connect(). Allocates the client's state (receive buffers, tables);
  // nothing else happens until Connect().
  Client(const ClientConfig& config, DatagramSocket* socket, ClientListener* listener = nullptr);
  ~Client();
  Client(const Client&) = delete;
  Client& operator=(const Client&) = delete;

  // Starts the handshake with the relay at `server`. `token` is the binary client token the
  // backend handed out (SignJoinToken's output; decode the printable form with
  // Base64UrlDecode): its relay part goes to the relay, its session secret never leaves this
  // client and authenticates the relay (an Accept without the relay's proof of it ends the
  // handshake in kRejected, reason BadProof: a man in the middle). Copied. `now`: seconds on
  // any monotonic clock, the same clock as every later call. kInvalidArgument if already
  // started, or if `server` or an entry of ClientConfig::relays is not a numeric address;
  // kMalformed, naming the cause, if `token` is not a client token (e.g. a relay part alone,
  // or an older token version). Nothing is sent then.
  Status Connect(const RelayAddress& server, std::span<const uint8_t> token, double now);

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
  // Grab with the hand's pose now (metres, unit quaternion; room frame): publishes it as the
  // hand's transform and sends it with the grab, so the relay judges the hover where the hand
  // is even if its move has not reached the relay yet (it refuses, GrabRefused, a pose more
  // than 0.5 m from the hand's last state it holds). kNotFound if this client does not own
  // `hand_id`; kInvalidArgument for a non-finite pose or a rotation that is not unit.
  Status GrabAt(uint32_t entity_id, uint32_t hand_id, const Vec3f& position, const Quatf& rotation);
  // Lets go: the entity leaves at the velocity the hand showed over its last ~0.1 s of published
  // transforms, spinning as the hand turned (throwing), then falls. kNotConnected before
  // OnJoined; OnError(NotOwner) follows if none of this client's hands holds it.
  Status Release(uint32_t entity_id);
  // Sends an application message on the reliable channel (ordered; fragmented as needed) to
  // `target` (`to_player` for kPlayer, else ignored); the relay forwards it with this player's
  // id (ClientListener::OnMessage) or refuses it with OnError (NotPermitted, OverBudget,
  // RateLimited, UnknownPlayer). kNotConnected before OnJoined, kInvalidArgument for a payload
  // over kMaxMessagePayload, an unknown target or a kPlayer target of 0, kResourceExhausted when
  // the reliable queue is full. The payload is copied.
  Status SendMessage(MessageTarget target, uint32_t to_player, std::span<const uint8_t> payload);
  // As SendMessage, but unreliable: the payload (at most kMaxUnreliableMessageBytes) leaves at
  // once in one datagram of its own and may be lost; each addressed member gets it at most
  // once and never after a later one of this client's unreliable messages
  // (ClientListener::OnUnreliableMessage). Same permission, budgets (shared with SendMessage)
  // and refusals (OnError). kTooLarge over kMaxUnreliableMessageBytes; kNotConnected,
  // kInvalidArgument as SendMessage. The payload is copied.
  Status SendMessageUnreliable(MessageTarget target, uint32_t to_player,
                               std::span<const uint8_t> payload);
  // Properties (docs/protocol.md, "Properties"). Writes `value` under `key` (1..64 bytes) of
  // the room (`entity_id` 0) or of an entity; the relay stores it and sends every member,
  // this client included, OnPropertyChanged with the new version. `authority` applies when
  // the write creates the property: kOwner (only the entity's owner, or for a room property
  // this player, may write it) or kAnyone; later writes keep it. Returns the request id that
  // OnPropertyChanged and OnPropertyConflict carry. The relay refuses with OnError
  // (NotPermitted, RateLimited, NotOwner, UnknownEntity, OverBudget naming the budget,
  // InvalidMessage). kNotConnected before OnJoined; kInvalidArgument for a bad key, a bad value
  // (unknown type, NaN/infinite double, vec3 or quat component, bool not 0/1, string/bytes
  // over kMaxPropertyValueBytes) or an unknown authority; kNotFound for an entity this client
  // does not know; kResourceExhausted when the reliable queue is full. Copies everything.
  Result<uint32_t> SetProperty(uint32_t entity_id, std::string_view key,
                               const PropertyValue& value,
                               PropertyAuthority authority = PropertyAuthority::kOwner);
  // As SetProperty, but the relay applies it only if the property's version is
  // `expected_version` (0: only if it does not exist); otherwise OnPropertyConflict with the
  // current value and version. Of concurrent writers expecting the same version exactly one
  // wins.
  Result<uint32_t> CompareAndSetProperty(uint32_t entity_id, std::string_view key,
                                         const PropertyValue& value, uint32_t expected_version,
                                         PropertyAuthority authority = PropertyAuthority::kOwner);
  // The property as the relay last announced it (this client's own writes included, once the
  // relay accepted them); null if unknown. Valid until the next Update() or room change.
  const PropertyRecord* FindProperty(uint32_t entity_id, std::string_view key) const;
  // Every property of the joined room, room properties first. An entity's properties go when it
  // is despawned; all go on leaving the room.
  const std::map<PropertyKey, PropertyRecord>& properties() const;

  // Ownership (docs/protocol.md, "Ownership"). Every entity has one owner, whose transforms the
  // relay accepts: a player, or the room (0). Changes take effect when the relay announces them
  // (ClientListener::OnOwnershipChanged, to every member, this client included): a client
  // keeps publishing an entity it hands over or releases until then, and the relay drops (and
  // counts, edgephys_stale_owner_states_total) what it sends after. Refusals arrive as
  // OnError(reason, entity_id, detail): TakeoverRefused (the owner forbids takeover, or PhyS
  // simulates the entity: grab it instead), NotOwner, UnknownEntity, UnknownPlayer,
  // NotPermitted (a join token without the Spawn permission, this player's or the receiver's),
  // RateLimited. Each call sends one reliable message: kNotConnected before OnJoined,
  // kResourceExhausted when the reliable queue is full.
  //
  // Asks for `entity_id` (known to this client): granted at once when the room owns it or its
  // owner allows takeover; an entity PhyS simulates is reclaimed (see ReleaseOwnership) unless
  // a hand holds it or it is a soft body (TakeoverRefused). kNotFound for an entity this client
  // does not know.
  Status RequestOwnership(uint32_t entity_id);
  // Gives an entity this client owns to `player_id`, a member of the room. kNotFound if not
  // owned; kInvalidArgument for player 0 or this player.
  Status HandOver(uint32_t entity_id, uint32_t player_id);
  // Gives an entity this client owns to the room (owner 0); anyone may then request it. It
  // stays in the room when this player leaves. A body this client simulates locally with a
  // dynamic rigid body (spawned without the Offloaded flag, so PhyS mirrors it) is offloaded:
  // PhyS simulates it from then on, starting from its latest state with `linear` (m/s) and
  // `angular` (rad/s, room frame) velocity, without a despawn; OnOwnershipChanged reports owner
  // 0, and its states come from PhyS. Requesting it back (RequestOwnership) reclaims it: the
  // requester's local physics starts from PhyS's pose and velocities (OwnedMotion).
  // kNotFound if not owned; kInvalidArgument for a non-finite velocity (the relay refuses
  // speeds over 1,000 with InvalidMessage).
  Status ReleaseOwnership(uint32_t entity_id, const Vec3f& linear = {}, const Vec3f& angular = {});
  // An owned entity's pose as last published and, for an entity just gained from PhyS, the
  // pose and velocities PhyS had at the change (m/s, rad/s; 0 for others): where the game's
  // local physics continues from. Null outputs are skipped. kNotFound if not owned.
  Status OwnedMotion(uint32_t entity_id, EntityState* state, Vec3f* linear = nullptr,
                     Vec3f* angular = nullptr) const;
  // Lets others take an entity this client owns by RequestOwnership (true) or not (false, the
  // default at spawn). The setting stays with the entity across changes of owner. kNotFound if
  // not owned.
  Status SetTakeoverAllowed(uint32_t entity_id, bool allowed);
  // Chooses what the relay does with an entity this client owns when its owner leaves or times
  // out (schema::OwnerLeave, EntitySpec::on_owner_leave): 0 default (Persistent: stay, else
  // despawn), 1 stay with the room at rest, 2 PhyS simulates it on from its last pose and
  // velocity (a dynamic body this client simulates; else stay), 3 despawn. Kept across owners;
  // announced to every member with OnOwnershipChanged (authority_seq unchanged).
  // kInvalidArgument for another value, kNotFound if not owned.
  Status SetOwnerLeave(uint32_t entity_id, uint8_t choice);
  // Whether this client owns (publishes) `entity_id`: its own spawns and entities it gained.
  bool Owns(uint32_t entity_id) const;
  // The owner of `entity_id` as this client knows it: player_id() for owned entities, 0 for the
  // room's and for entities this client does not know.
  uint32_t OwnerOf(uint32_t entity_id) const;

  // Records the latest transform of an owned entity; it goes out at the publish rate.
  // kNotFound if not owned, kInvalidArgument if not finite / not unit.
  Status PublishTransform(uint32_t entity_id, const Vec3f& position, const Quatf& rotation);

  // Sends a disconnect (kClientLeft) to the relay.
  void Disconnect();

  ClientState state() const;
  bool joined() const;
  uint32_t player_id() const;
  uint32_t entity_id_base() const;
  // The state format the joined room sends (its Joined message; docs/protocol.md §5): 9 (the
  // default), 2, or a plug-in's (ClientConfig::state_decoder); 0 before the first Joined. Kept after a leave until
  // the next Joined.
  uint8_t state_format() const;
  const std::string& room() const;
  uint16_t reject_reason() const;
  DisconnectReason disconnect_reason() const;
  // The relay's text for why it is ending this connection (an operator's kick, room close or
  // drain: ControlMessage Disconnecting, docs/protocol.md), set when that message arrives,
  // before the Disconnect itself (so it is there when OnDisconnected runs). Empty otherwise.
  const std::string& disconnect_detail() const;
  // nullptr before kConnected; points into the client (valid until the next non-const call).
  const ConnectionStats* stats() const;
  // Others' entities (and own entities are not listed). References and pointers into the
  // table stay valid until the next Update() or room change.
  const std::unordered_map<uint32_t, RemoteEntity>& entities() const;
  const RemoteEntity* FindEntity(uint32_t id) const;
  const std::vector<uint32_t>& players() const;
  // Bytes of state payload received (all formats), for bandwidth measurements.
  uint64_t state_bytes_received() const;
  // State payloads that arrived while not in a room, and were dropped. The relay sends a
  // member states only after it has acknowledged its Joined message, so in a room this stays 0;
  // late payloads from a room just left land here.
  uint64_t state_payloads_outside_room() const;
  // State payloads refused: malformed, or of a format the SDK does not decode (and no
  // ClientConfig::state_decoder does).
  uint64_t state_payloads_refused() const;
  // Arrival time (as RemoteEntity::arrival_unix_s: Unix seconds, CLOCK_REALTIME) of the
  // datagram Update() read last. Inside a listener callback run by Update() it is the datagram
  // that delivered what the callback reports (for a reliable message: the datagram that
  // completed it or, after a loss, the resend that let it through in order). 0 before any
  // datagram or unless ClientConfig::record_arrival_times.
  double packet_arrival_unix_s() const;
  // Datagrams whose arrival time is the time of the read, because the socket gave none
  // (arrival times unsupported, e.g. a simulated network, or no timestamp from the OS). Only
  // counted with ClientConfig::record_arrival_times.
  uint64_t arrival_time_fallbacks() const;
  // Cluster: signed redirects followed and refused (forged, expired, or too many); sessions
  // resumed after a relay was lost (ClientConfig::resume); whether one is under way; the relay
  // this client talks to now.
  uint64_t redirects_followed() const;
  uint64_t redirects_refused() const;
  uint64_t resumes() const;
  // After resumes: owned entities whose Spawn was sent again (RespawnAfterResume in
  // client/client_resume.cc), those of them the restored room already held, and owned
  // entities reported lost (OnError "lost in failover: ...").
  uint64_t respawns_sent() const;
  uint64_t respawns_duplicate() const;
  uint64_t entities_lost() const;
  bool resuming() const;
  RelayAddress server() const;
  // Datagrams from the relay's address that failed authentication or were replays (dropped).
  uint64_t packets_refused() const;
  // Unreliable application messages received and handed to the listener, and those dropped:
  // older than (or the same as) one already delivered from their sender (`stale`), or
  // malformed (shorter than their header, unknown target, no sender).
  uint64_t unreliable_messages_received() const;
  uint64_t unreliable_messages_stale() const;
  uint64_t unreliable_messages_malformed() const;

 private:
  // Raw senders and the control-message hook for tests, fuzzers and the PhyS worker:
  // client/client_testing.h.
  friend class ClientTesting;
  friend class ProtocolPeer;
  class Impl;  // client.cc
  std::unique_ptr<Impl> impl_;
};

}  // namespace edgephys
