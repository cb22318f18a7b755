// ccu: concurrent users against one relay with embedded PhyS.
//
// Bots join gradually (--users over --ramp seconds), spread over --rooms rooms. Each bot owns a
// head (Avatar, kinematic, no collider), two hands (Hand, kinematic, with trigger spheres:
// mirrored into PhyS) and one interactable box simulated by PhyS, which it grabs (hand moved
// onto it, Grab), carries and releases now and then. All move constantly.
//
// The relay runs on its own thread (as in production); bots run on the calling thread. Every
// second a sample records users, relay egress/ingress, updates/s, reliable resends and the
// relay thread's CPU share. User-to-user latency: each bot watches other bots' right hands;
// a received pose is matched to the publish time of the same pose on the sender (all in one
// process and clock), so latency = receive time - publish time; grab latency = the Grab
// request to the Grabbed event at another user. The sender is found by (room, entity id):
// rooms reuse entity ids (loadgen/pose_history.h). Each is measured twice:
//   * SDK latency (latency_ms_*, grab_latency_ms_*): from the start of the sender's bot pass
//     to the receiving bot's callback (steady clock). It includes the wait of a datagram in
//     the receiver's socket until the single bot thread reaches that bot, up to a whole bot
//     pass: a load-generator artifact a headset, reading its own socket, does not have.
//   * arrival latency (arrival_latency_ms_*, grab_arrival_latency_ms_*): from the sender's
//     PublishTransform()/Grab() call to the kernel's receive timestamp of the datagram that
//     carried the pose/event to the receiver (ClientConfig::record_arrival_times), both on
//     CLOCK_REALTIME, so no clock conversion. Never above the SDK latency of the same sample.
// Reliable loss: every bot checks it received every spawn and grab/release event of the other
// bots in its room, once each.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

struct CcuOptions {
  std::vector<uint32_t> users = {100};  // one run per count
  uint32_t rooms = 1;
  double ramp_s = 10;
  double duration_s = 20;                // measured after the ramp
  double tick_rate_hz = 60;
  double publish_hz = 30;                // bots' pose updates
  uint64_t seed = 1;
  size_t relay_threads = 1;              // relay worker threads (ticks and PhyS), its own included
  bool shared_encoding = true;           // the in-process relay's rooms use state format 9 (false: 2)
  bool packet_auth = true;               // the in-process relay seals packets (RelayConfig)
  bool progress = true;
  // --relay: bots join an external edgephys-relay; server-side figures from its /metrics.
  ExternalRelayOptions external;
  // Every bot decodes what it receives (the SDK has no acknowledge-only mode), but only every
  // `measure_every`-th bot matches poses for latency and keeps jitter buffers (1: all bots).
  uint32_t measure_every = 1;
  // --impaired: this fraction of the bots (every 1/f-th, spread over the rooms) reach the
  // relay over a link of their own that loses --impaired-loss of the datagrams and delays them
  // --impaired-delay-ms, both directions (protocol/network_simulator.h, in the bot process).
  double impaired_fraction = 0;
  double impaired_loss = 0.10;
  double impaired_delay_ms = 30;
  // --samples: every latency sample as a CSV line (kind, time, rooms, bots, entity, ms), and
  // every measured hand pose that matched no publish; empty: none written.
  std::string samples_path;
};

// Member names are the --json field names of a "series" sample.
struct CcuSample {
  double t = 0;
  uint32_t users = 0;
  double egress_bytes_per_s = 0;   // relay total
  double ingress_bytes_per_s = 0;
  double updates_per_s = 0;        // entity updates sent by the relay
  double resends_per_s = 0;
  double relay_cpu = 0;            // relay thread CPU time / wall time (1.0 = one core); NaN unknown
  double physics_step_ms = 0;      // mean over the second
};

struct CcuResult {
  uint32_t users = 0;
  uint32_t rooms = 0;
  uint32_t connected = 0;          // bots connected and joined at the end
  uint64_t reliable_expected = 0;
  uint64_t reliable_lost = 0;      // expected reliable messages not received (spawns, grab events)
  uint64_t reliable_duplicated = 0;
  double latency_ms_p50 = 0, latency_ms_p99 = 0;   // hand pose, user to user
  double grab_latency_ms_p50 = 0, grab_latency_ms_p99 = 0;
  double arrival_latency_ms_p50 = 0, arrival_latency_ms_p99 = 0;  // to the receiver's socket
  double grab_arrival_latency_ms_p50 = 0, grab_arrival_latency_ms_p99 = 0;
  // Datagrams the bots timed at their read because the kernel gave no timestamp (expected 0).
  uint64_t arrival_time_fallbacks = 0;
  double relay_wait_ms_mean = 0;   // half a tick: expected relay queueing delay
  double physics_step_ms_p99 = 0;
  // One pass of the load generator over all its bots (receive, decode, publish): a delay the
  // bots add on both ends that a real client, with one connection, does not have.
  double bot_pass_ms_p50 = 0;
  double bot_pass_ms_p99 = 0;
  double interpolation_delay_ms = 0;  // playout delay a jitter buffer chooses for these arrivals
  double relay_cpu_mean = 0;
  double egress_bytes_per_s_per_user = 0;
  // Per entity update the relay delivered (updates_per_s), over the measured seconds: its CPU
  // (microseconds; NaN when the CPU is unknown) and the sealed UDP payload bytes it sent.
  double relay_us_per_update = 0;
  double bytes_per_update = 0;
  double expected_update_ratio = 0;   // hand updates received / expected
  // Measurement soundness. Of the hand updates measured (new poses at a measuring bot), those
  // matched to their publish give the latency samples; unmatched ones matched no publish of
  // the last ~2 s (older than that, or a matching bug): they are not in the percentiles, so
  // a non-zero count means the p99 may hide a tail. Cross-room: samples (hand or grab) timed
  // against a publisher or grabber in another room than the receiver's (a keying bug; 0).
  uint64_t hand_updates_measured = 0;
  uint64_t hand_unmatched = 0;
  uint64_t cross_room_samples = 0;
  // --impaired: bots on the lossy link, and the datagrams their links dropped (to the relay,
  // from the relay).
  uint32_t impaired_users = 0;
  uint64_t impaired_dropped_up = 0, impaired_dropped_down = 0;
  std::vector<CcuSample> series;
  // External relay: scrapes of /metrics that failed (their seconds have no server figures).
  uint32_t metrics_failures = 0;
  std::string metrics_error;  // the last failure
};

std::vector<CcuResult> RunCcu(const CcuOptions& options);

}  // namespace edgephys::loadgen
