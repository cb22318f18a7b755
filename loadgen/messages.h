// messages: how many application messages one relay core forwards in a room, and what a
// property update costs on the wire (issue 31's figures).
//
// Phase 1 (--warmup, then --duration measured): --users bots join room "messages"; each sends
// --rate messages per second of --payload bytes to the whole room (target Room: each message
// is delivered to every member, the sender included), reliable or, with --unreliable, one
// datagram each. Measured over the window: messages accepted by the relay per second (sent by
// the bots), copies delivered per second (received by the bots' SDKs), the relay thread's CPU
// seconds per second (in-process: the relay's own thread, as ccu measures it; --relay: the
// process's, from /proc/<pid>/stat with --relay-pid), and so delivered messages per relay
// core-second. Room budgets are lifted in-process (the measurement is the forwarding, not the
// rate limits); an external relay keeps its own (refusals are counted and reported).
//
// Phase 2 (bytes per property update): in a room of two ("properties"), one bot writes a room
// property (an int64 under a 4-byte key, kAnyone) --property-hz times per second for
// --property-seconds; the other only listens. Bytes are UDP payloads as on the wire (sealed
// datagrams: ConnectionStats::bytes_*, IP/UDP headers excluded), taken from both clients'
// connections: the writer's bytes sent per write (client -> relay) and the listener's bytes
// received per write (relay -> one member), each also net of the same connection's idle
// traffic (keep-alives, acknowledgements) measured over an equal window before the writes.
// The control message itself (ControlMessage{PropertySet}) is reported too.
//
// Bots run on the calling thread; the relay on its own. No figure is asserted here; the smoke
// test checks only that messages flowed and nothing was lost (reliable mode).
#pragma once

#include <cstdint>
#include <string>

#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

struct MessagesOptions {
  uint32_t users = 25;
  double rate_hz = 40;        // messages per second per bot
  uint32_t payload_bytes = 32;
  bool unreliable = false;
  double warmup_s = 1;
  double duration_s = 5;
  double tick_rate_hz = 60;
  double property_hz = 30;
  double property_seconds = 2;
  bool packet_auth = true;    // the in-process relay seals packets
  bool progress = true;
  ExternalRelayOptions external;
};

struct MessagesResult {
  uint32_t joined = 0;                 // bots in the room at the start of the window
  double window_s = 0;
  uint64_t sent = 0;                   // messages the bots sent in the window
  uint64_t send_refused = 0;           // refused by the SDK (a full reliable queue)
  uint64_t received = 0;               // copies delivered to bots in the window
  uint64_t relay_refusals = 0;         // Error events at the senders (budgets)
  double sent_per_s = 0;
  double delivered_per_s = 0;
  double relay_cpu = kUnknown;         // relay CPU seconds per second (1.0 = one core)
  double delivered_per_core_s = kUnknown;
  double accepted_per_core_s = kUnknown;
  double relay_egress_bytes_per_s = 0;
  // Reliable mode: after the window, every message a bot sent arrived at every member exactly
  // once (copies expected vs received, including the tail sent before the window closed).
  uint64_t expected_total = 0, received_total = 0, duplicates = 0;
  // Phase 2.
  uint64_t property_writes = 0;        // writes announced back to the writer
  uint32_t property_message_bytes = 0; // ControlMessage{PropertySet} as the writer sends it
  double property_sent_bytes = 0;      // writer's bytes sent per write (all its traffic)
  double property_received_bytes = 0;  // listener's bytes received per write
  double property_sent_net_bytes = 0;  // the same, less the idle traffic of the same window
  double property_received_net_bytes = 0;
};

MessagesResult RunMessages(const MessagesOptions& options);

}  // namespace edgephys::loadgen
