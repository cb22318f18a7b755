// Session: one admitted client on the relay: its connection, identity (from the join token),
// the room it joined and what it has acknowledged of that room's state. Owned by the Relay and
// used only on its thread (Replicate() may run on a pool thread during a parallel tick).
//
// Dispatch: messages about the room (spawn, despawn, grab, release, states) go straight to the
// RoomHost the session joined; joining, leaving and PhyS worker messages go to the SessionHost
// (the relay), which owns rooms and workers. As a MemberLink it is how its room reaches it.
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "protocol/connection.h"
#include "protocol/datagram_socket.h"
#include "protocol/packet_seal.h"
#include "relay/member_link.h"
#include "relay/physics_link.h"
#include "relay/rate_limit.h"
#include "relay/relay_config.h"
#include "relay/replication.h"

namespace edgephys {

class RoomHost;
class Session;

// What a session needs from the relay that owns it.
class SessionHost {
 public:
  virtual ~SessionHost() = default;
  virtual void OnJoinRoom(Session& s, std::string_view room, double now) = 0;
  virtual void OnLeaveRoom(Session& s, double now) = 0;
  virtual void OnWorkerHello(Session& s) = 0;
  virtual void OnWorkerResult(Session& s, const schema::WorkerResult& result) = 0;
  virtual void OnWorkerStates(Session& s, std::span<const uint8_t> payload) = 0;
  // Sends one datagram on the relay's socket (counted there).
  virtual void Transmit(const Endpoint& to, std::span<const uint8_t> datagram) = 0;
  // `s` has something to send or a timer to rework: service it at the next sessions pass.
  // Called once each time the session goes from waiting on a timer to due, always on the
  // relay thread (a session made due in a parallel room tick reports it at its flush).
  virtual void OnServiceSoon(Session& s) = 0;
};

class Session final : public ConnectionHandler,
                      public PacketWriter,
                      public WorkerChannel,
                      public MemberLink {
 public:
  // `host` and `counters` are not owned and must outlive the session.
  Session(SessionHost* host, RelayCounters* counters, const Endpoint& endpoint,
          uint32_t connection_id, uint32_t player_id, uint32_t permissions,
          std::string token_room, uint64_t token_nonce, const ConnectionConfig& config,
          const AbuseLimits& limits, double now);

  // ConnectionHandler: messages from the client.
  void OnReliableMessage(std::span<const uint8_t> message) override;
  void OnUnreliablePayload(uint16_t sequence, std::span<const uint8_t> payload) override;
  void OnPacketAcked(uint16_t sequence) override;
  // PacketWriter: packets to the client (held while a buffered Replicate runs).
  void WritePacket(std::span<const uint8_t> packet) override;
  // WorkerChannel: when this session is a PhyS worker.
  bool SendToWorker(std::span<const uint8_t> message) override {
    ServiceSoon();
    return connection_.SendReliable(message).ok();
  }
  bool WorkerConnected() const override { return connection_.connected(); }

  // MemberLink: how its room reaches it.
  uint32_t player_id() const override { return player_id_; }
  uint32_t permissions() const override { return permissions_; }
  bool AllowSpawn(double now) override { return spawns_.Take(now); }
  bool SendReliable(std::span<const uint8_t> message) override;
  bool SendUnreliable(std::span<const uint8_t> payload, double now) override;
  size_t ReliablePending() const override { return connection_.stats().pending_reliable_bytes; }
  size_t ReliableCapacity() const override { return reliable_capacity_; }
  void Overflow() override { connection_.Disconnect(DisconnectReason::kReliableOverflow, *this); }
  void SendError(schema::RejectReason reason, uint32_t entity_id,
                 std::string_view detail) override;
  void DropPayload(DropReason reason) override;
  void DropUpdate(DropReason reason) override;
  void StartReplication(const ReplicationConfig& config) override;
  bool ReadyForStates() const override;
  void Replicate(const ReplicationFrame& frame, double now, RelayCounters& counters,
                 bool buffered) override;
  void FlushReplication() override;
  void Forget(uint32_t entity_id) override { replicator_->Forget(entity_id); }

  bool is_worker() const { return is_worker_; }
  void set_worker(bool worker) { is_worker_ = worker; }
  // Rate limits (AbuseLimits); workers are exempt from the packet limits.
  // Packet authentication: from now on every packet to the client is sealed and every packet
  // from it must open (protocol/packet_seal.h).
  void EnableSeal(const ConnectionKeys& keys);
  bool sealed() const { return seal_ != nullptr; }
  // Opens a sealed datagram from the client; empty with `*reason` (kBadAuth, kReplayed,
  // kTooShort) when it must be dropped. The span is valid until the next call.
  std::span<const uint8_t> Open(std::span<const uint8_t> datagram, DropReason* reason);
  bool AllowPacket(double now, size_t bytes) {
    return is_worker_ || (packets_.Take(now) && bytes_.Take(now, static_cast<double>(bytes)));
  }
  double connected_at() const { return connected_at_; }

  // An operator ends this connection (a kick, its room closed, a drain; docs/admin-api.md):
  // queues Disconnecting{reason, detail} (detail cut to kMaxCloseDetail bytes) and from then on
  // ignores what the client sends. The relay ends the connection with `reason` once CloseDue().
  void BeginClose(DisconnectReason reason, std::string_view detail, double now);
  bool closing() const { return closing_; }
  // A closing session's Disconnecting was acknowledged, or kCloseGraceS passed.
  bool CloseDue(double now) const {
    return closing_ && (connection_.reliable_acked_end() >= close_acked_end_ ||
                        now >= close_deadline_);
  }
  DisconnectReason close_reason() const { return close_reason_; }
  static constexpr size_t kMaxCloseDetail = 256;
  static constexpr double kCloseGraceS = 1.0;

  Connection& connection() { return connection_; }
  const Connection& connection() const { return connection_; }
  const Endpoint& endpoint() const { return endpoint_; }
  const std::string& token_room() const { return token_room_; }
  uint64_t token_nonce() const { return token_nonce_; }
  // The room joined, null if none. Set by the relay on join and cleared on leave.
  RoomHost* room() const { return room_; }
  void set_room(RoomHost* room) { room_ = room; }
  // What this client has of the joined room's state; reset on every join.
  const ClientReplicator& replicator() const { return *replicator_; }
  // Accept datagram re-sent when the client repeats its Connect (the first was lost).
  std::vector<uint8_t>& accept_packet() { return accept_packet_; }
  double now() const { return now_; }
  void set_now(double now) { now_ = now; }

  // When the relay must next service this session's connection (Relay::UpdateSessions calls
  // Connection::Update only on sessions that are due): the connection's next timer, or at
  // once (-infinity) after anything used it: a packet from the client, a reliable message
  // queued, a replication tick, a close begun. The relay sets it after each service.
  double service_at() const { return service_at_; }
  void set_service_at(double at) { service_at_ = at; }
  void ServiceSoon() {
    if (service_at_ == -std::numeric_limits<double>::infinity()) return;  // already due
    service_at_ = -std::numeric_limits<double>::infinity();
    // In a buffered (parallel) Replicate this runs on a pool thread beside other rooms' ticks:
    // the relay's list is told at FlushReplication, which runs on the relay thread.
    if (buffering_) {
      due_at_flush_ = true;
      return;
    }
    host_->OnServiceSoon(*this);
  }
  // Reassembly bytes of this connection last added to RelayCounters::reassembly_held_bytes
  // (Connection::reliable_partial_bytes() when the relay last looked; 0 once evicted).
  size_t held_published() const { return held_published_; }
  void set_held_published(size_t bytes) { held_published_ = bytes; }
  double close_deadline() const { return close_deadline_; }

 private:
  SessionHost* host_;
  RelayCounters* counters_;
  Endpoint endpoint_;
  Connection connection_;
  uint32_t player_id_;
  uint32_t permissions_;
  std::string token_room_;
  uint64_t token_nonce_;
  // States are sent to a member only once it has acknowledged its Joined message (reliable
  // stream position): before that, a reordered state payload could reach the client before
  // Joined, where it cannot be decoded although the connection acknowledges it, and the delta
  // encoder would then reference a baseline the client never had.
  uint64_t states_after_reliable_ = 0;
  RoomHost* room_ = nullptr;
  std::unique_ptr<ClientReplicator> replicator_;
  std::vector<uint8_t> accept_packet_;
  bool is_worker_ = false;
  bool closing_ = false;
  // The newest client-side number of an unreliable application message this connection
  // forwarded: an older or repeated one is dropped as stale (in order per sender).
  uint32_t newest_message_sequence_ = 0;
  DisconnectReason close_reason_ = DisconnectReason::kNone;
  uint64_t close_acked_end_ = 0;
  double close_deadline_ = 0;
  bool buffering_ = false;
  bool due_at_flush_ = false;  // made due in a buffered Replicate: tell the host at the flush
  std::vector<std::vector<uint8_t>> outbox_;  // capacity reused between ticks
  size_t outbox_size_ = 0;
  double now_;
  double service_at_ = -std::numeric_limits<double>::infinity();
  size_t held_published_ = 0;
  TokenBucket packets_, bytes_, spawns_;
  double connected_at_;
  size_t reliable_capacity_;  // ConnectionConfig::max_pending_reliable_bytes
  std::unique_ptr<PacketSeal> seal_;
  std::vector<uint8_t> seal_buffer_, open_buffer_;
};

}  // namespace edgephys
