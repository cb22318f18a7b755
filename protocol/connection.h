// Connection: one established edgephys connection, both ends (relay and client use the same
// class). It owns the per-connection protocol state and nothing else: no socket, no clock.
// Time is injected (`now`, seconds on any monotonic clock) and packets leave through a
// PacketWriter, so a test can pump two Connections in one thread deterministically.
//
// Wire format of the packets it produces (docs/protocol.md, "Data packets"):
//   packet prefix (packet.h, type kData or kDisconnect, connection id)
//   u16 sequence, u16 ack, u32 ack_bits          (little-endian; ack_bits bit i = ack-1-i seen)
//   chunks until the end of the packet:
//     u8 0x01 reliable unit: u16 unit id, u8 flags (bit0: last unit of its message), u16 len, bytes
//     u8 0x02 unreliable payload: u16 len, bytes (at most one per packet)
//   kDisconnect: one byte DisconnectReason instead of chunks.
//
// Channels:
//  * Reliable-ordered: SendReliable() queues a message; it is cut into units of at most
//    kMaxReliableUnitSize bytes, each resent on an RTT-based timeout until the packet carrying
//    it is acknowledged. New units leave on the next Update() or ride on an unreliable payload's
//    packet if one leaves first. The receiver drops duplicate units and delivers whole messages exactly
//    once, in send order. Receive-side memory (the message being reassembled, out-of-order
//    units, their buffers) stays under max(ConnectionConfig::max_held_reliable_bytes,
//    max_message_size) plus kReliableHeldSlack (1 MiB + 192 KiB by default): a packet that
//    would need more and does not carry the next unit of the stream is refused
//    unacknowledged (resent later), so an honest peer only slows down.
//  * Unreliable-sequenced: SendUnreliable() sends one packet now. The receiver delivers its
//    payload only if the packet is newer than every unreliable payload it has delivered
//    (older ones are dropped as stale and counted). A packet with a stale payload is dropped
//    whole (reliable units riding on it are resent) and not acknowledged, so OnPacketAcked()
//    on the sender means "delivered". Exception: a payload whose first byte is
//    kUnorderedPayloadFormat (an unreliable application message, which carries its own
//    per-sender sequence) is delivered whenever its packet is new, in any order, and neither
//    is dropped by nor moves the state payloads' newest sequence.
//
// Thread-safety: none. One thread owns a Connection (the room's thread on the relay).
// Cost: ProcessPacket and SendUnreliable are O(packet size) and allocate nothing once the
// connection has reached its steady-state buffers.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <deque>
#include <span>
#include <vector>

#include "protocol/connection_types.h"
#include "protocol/packet.h"
#include "protocol/status.h"

namespace edgephys {

// First byte of an unreliable payload that skips the sequenced-stale check (see above).
inline constexpr uint8_t kUnorderedPayloadFormat = 15;

inline constexpr size_t kConnectionHeaderSize = kPacketPrefixSize + 8;
inline constexpr size_t kMaxReliableUnitSize = 1024;
inline constexpr uint16_t kReliableWindow = 1024;  // units in flight / buffered, each way
// Receive-side memory a Connection may hold beyond max(ConnectionConfig::max_held_reliable_bytes,
// max_message_size):
// one datagram's units, the out-of-order slot table (kReliableWindow small records), the
// growth step of the message buffer and the buffers kept for reuse (bytes).
inline constexpr size_t kReliableHeldSlack = 192 * 1024;
// Largest unreliable payload that fits one packet with its chunk header.
inline constexpr size_t kMaxUnreliablePayload = kMaxPacketSize - kConnectionHeaderSize - 3;

// Where a Connection writes each packet it produces. The span is valid only during the call.
class PacketWriter {
 public:
  virtual ~PacketWriter() = default;
  virtual void WritePacket(std::span<const uint8_t> packet) = 0;
};

// What a Connection reports while processing a packet. Spans are valid only during the call.
class ConnectionHandler {
 public:
  virtual ~ConnectionHandler() = default;
  // A whole reliable message, in order, exactly once.
  virtual void OnReliableMessage(std::span<const uint8_t> message) = 0;
  // The unreliable payload of packet `sequence`, newer than every payload delivered before.
  virtual void OnUnreliablePayload(uint16_t sequence, std::span<const uint8_t> payload) = 0;
  // One of our packets (as numbered by SendUnreliable) was acknowledged by the peer.
  // Called at most once per sequence; packets never acknowledged are never reported.
  virtual void OnPacketAcked(uint16_t sequence) { (void)sequence; }
};

class Connection {
 public:
  Connection(uint32_t connection_id, const ConnectionConfig& config, double now);
  ~Connection();
  Connection(const Connection&) = delete;
  Connection& operator=(const Connection&) = delete;

  uint32_t id() const { return connection_id_; }

  // Queues `message` (1 .. config.max_message_size bytes) on the reliable channel; it goes out
  // on the next Update(). Errors: kTooLarge, kQueueFull (pending bytes limit), kNotConnected.
  Status SendReliable(std::span<const uint8_t> message);
  // Positions in the reliable stream, in bytes since the connection opened. A message queued
  // when reliable_queued_end() was E has been received by the peer (and, the channel being
  // ordered, delivered with everything before it) once reliable_acked_end() >= E.
  uint64_t reliable_queued_end() const;
  uint64_t reliable_acked_end() const;

  // Sends one packet now carrying `payload` (1 .. kMaxUnreliablePayload bytes), the current
  // acks, and the due reliable units that fit beside the payload (new ones first; they would
  // otherwise leave in packets of their own on the next Update()). Returns the packet
  // sequence, which OnPacketAcked() later reports if it arrives. A receiver drops a packet
  // whose payload is stale whole, units included (resent), so an ack still means "delivered".
  Result<uint16_t> SendUnreliable(std::span<const uint8_t> payload, double now, PacketWriter& out);

  // Parses a kData or kDisconnect packet addressed to this connection (the caller matched the
  // prefix's connection id and the sender's address). Reports deliveries to `handler`. A
  // malformed packet changes no state and returns kMalformed; a kDisconnect packet marks the
  // connection disconnected with the peer's reason.
  // Other results: kAlreadyExists for a duplicate (or too old) packet sequence (counted in
  // stats.duplicates_dropped, nothing else changes); kQueueFull when its reliable units would
  // pass max_held_reliable_bytes (counted in stats.reassembly_refused; only its acks apply, it
  // is not acknowledged and the peer resends it); kTooLarge (reassembly beyond
  // max_message_size) or kResourceExhausted (reliable unit beyond the window): the peer broke
  // the protocol, the connection is disconnected with kProtocolError and the next Update()
  // sends the disconnect packets; kNotConnected once disconnected. A stale unreliable payload
  // is dropped (Ok, counted in stats.stale_dropped); a packet carrying nothing else is then
  // not acknowledged.
  Status ProcessPacket(std::span<const uint8_t> packet, double now, ConnectionHandler& handler);

  // Sends due reliable units (new ones, then those whose resend timeout expired), acks the
  // peer is owed (an ack owed only for unreliable payloads once it has waited
  // ConnectionConfig::max_ack_delay_s for a packet of ours to carry it) and keep-alives;
  // detects the timeout. Call at least every few milliseconds
  // to tens of milliseconds. Sends at most 16 data packets per call (the peer can acknowledge
  // only 33 packets per packet it sends), so reliable throughput scales with the call rate.
  // A packet with no chunks (ack-only or keep-alive) does not itself ask for an ack.
  void Update(double now, PacketWriter& out);

  // The earliest time (seconds, the clock of `now`) at which Update() has something to send or
  // check: a due or held new reliable unit, a resend, an owed ack, a keep-alive, the silence
  // timeout; +infinity once disconnected with nothing left to send. The relay services a session
  // again by then. Valid until the
  // connection is next used (ProcessPacket, SendReliable, SendUnreliable, Update). O(units in
  // flight, at most 64 looked at).
  double NextTimer() const;

  // Sends `reason` to the peer (a few redundant copies, as it is not acknowledged) and marks
  // the connection disconnected. Idempotent.
  void Disconnect(DisconnectReason reason, PacketWriter& out);

  // Changes the silence timeout (e.g. shorter for relay <-> worker links). Seconds, > 0.
  void SetTimeout(double timeout_s);
  // Bytes every datagram carries beyond the packet this connection writes or reads: the seal's
  // kSealOverhead (protocol/packet_seal.h) once the packets are sealed, so that stats() count
  // the UDP payload as it goes on the wire. 0 by default (unsealed). O(1).
  void SetDatagramOverhead(size_t bytes) { datagram_overhead_ = bytes; }

  bool connected() const { return disconnect_reason_ == DisconnectReason::kNone; }
  DisconnectReason disconnect_reason() const { return disconnect_reason_; }
  const ConnectionStats& stats() const { return stats_; }
  // Bytes of reassembly memory held for the peer's partial reliable messages (allocated
  // capacity: the message being reassembled, out-of-order units, their slot table). O(1).
  size_t reliable_held_bytes() const;
  // The part of it that belongs to messages in progress (a message with units received but
  // not its last, out-of-order units); the rest is buffers kept for reuse. O(1).
  size_t reliable_partial_bytes() const;

 private:
  struct Impl;
  uint32_t connection_id_;
  DisconnectReason disconnect_reason_ = DisconnectReason::kNone;
  ConnectionStats stats_;
  size_t datagram_overhead_ = 0;  // SetDatagramOverhead
  Impl* impl_;  // owned; the channel state (kept out of the header)
};

}  // namespace edgephys
