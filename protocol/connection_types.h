// The plain value types of a Connection (protocol/connection.h) that its users configure and
// read: why a connection ended, its limits and timers, and its live statistics. Apart so that
// the client SDK's public header (client/client.h) can expose them without the connection's
// machinery.
//
// Thread-safety: values. Units: seconds, bytes, fractions in 0..1.
#pragma once

#include <cstddef>
#include <cstdint>

namespace edgephys {

// Stable numbers (they travel in kDisconnect packets and in schema/control.fbs).
enum class DisconnectReason : uint8_t {
  kNone = 0,
  kTimeout,
  kClientLeft,
  kServerShutdown,
  kKicked,
  kProtocolError,     // the peer broke the protocol (oversized message, window overrun)
  kReliableOverflow,  // our own reliable queue for this peer is full
};

struct ConnectionConfig {
  double keepalive_interval_s = 0.1;  // send at least one packet this often
  double timeout_s = 5.0;             // nothing received for this long: disconnect (kTimeout)
  size_t max_message_size = 1 << 20;  // reliable message limit, both ways (bytes)
  // Receive side: reassembly and out-of-order memory one peer can make us hold (bytes). A
  // packet whose reliable units would need more, and that does not continue the stream, is
  // refused unacknowledged (the peer resends it). Held memory stays under this plus
  // kReliableHeldSlack, or max_message_size plus it if that is larger (protocol/connection.h;
  // docs/protocol.md "Reliable-ordered channel").
  size_t max_held_reliable_bytes = 1 << 20;
  size_t max_pending_reliable_bytes = 8 << 20;  // SendReliable() beyond this: kQueueFull
  double min_resend_s = 0.03;         // floor of the RTT-based resend timeout
  double max_resend_s = 1.0;          // ceiling of the resend timeout
  // How long an acknowledgement owed for unreliable payloads may wait for a packet that
  // leaves anyway (the next unreliable payload or reliable unit carries it) before Update()
  // sends an ack-only packet. 0: the next Update() acknowledges (the client's default). A
  // packet with reliable units is always acknowledged by the next Update(). The relay uses
  // 20 ms (RelayConnectionDefaults, relay/relay_config.h): its rooms' state datagrams (every
  // 1/60 s) carry the acks, so it seals and sends about half as many datagrams.
  double max_ack_delay_s = 0;
};

// Real-time status of one connection (GameNetworkingSockets style); the relay exports it.
// IPv4 (20) and UDP (8) header bytes of every datagram (IPv6: 48), for reports that show what
// the network carries beside the UDP payload.
inline constexpr size_t kIpUdpHeaderBytes = 28;

struct ConnectionStats {
  // Smoothed round-trip time. Includes how long the peer held its acknowledgement: a relay
  // waits up to its ConnectionConfig::max_ack_delay_s (edgephys-relay --ack-delay, 0.02 s by
  // default) before acknowledging state-only packets, so a client's figure reads 0-20 ms
  // above the network's (about half that on average); acknowledgements of reliable
  // messages are never held.
  double rtt_s = 0;
  double rtt_var_s = 0;         // round-trip time variation
  double loss = 0;              // smoothed fraction of our packets not acknowledged (0..1)
  uint64_t packets_sent = 0;
  uint64_t packets_received = 0;
  // UDP payload bytes as on the wire: every packet plus, once the connection is sealed, the
  // seal's 24 bytes (Connection::SetDatagramOverhead). IP and UDP headers are not included: add
  // kIpUdpHeaderBytes per packet for what the network carries.
  uint64_t bytes_sent = 0;
  uint64_t bytes_received = 0;
  uint64_t reliable_resends = 0;    // reliable units sent more than once
  uint64_t reliable_delivered = 0;  // whole reliable messages delivered to the handler
  uint64_t stale_dropped = 0;       // unreliable payloads dropped as older than delivered
  uint64_t duplicates_dropped = 0;  // packets or reliable units received twice
  // Packets refused unacknowledged because their reliable units would have passed
  // ConnectionConfig::max_held_reliable_bytes (ProcessPacket returned kQueueFull).
  uint64_t reassembly_refused = 0;
  size_t pending_reliable_bytes = 0;  // queued or unacknowledged reliable bytes
};

}  // namespace edgephys
