// ceiling: the relay's datagram throughput beside the loopback ceiling that iperf3 measures in
// the same run, as a ratio.
//
// Per repetition:
//   1. For each --io-threads value: the relay runs in-process on its own thread(s) (1: one
//      Relay driven as edgephys-relay drives it; N>1: RelayShards) on 127.0.0.1. Bots (the
//      client SDK, all on the calling thread) connect, join --rooms rooms, spawn entities and
//      publish moving poses; the relay sends every moving entity to every other member of its
//      room each tick (ReplicationConfig::fixed_rate_hz = the tick rate). After a warm-up, the
//      relay's counters are read over the measured window: packets/s = (received + sent) / s,
//      bytes/s likewise (UDP payload bytes).
//   2. iperf3 -s -1 and iperf3 -u -c 127.0.0.1 -b 0 -l L -t T --json on loopback, L = the
//      relay's mean datagram size in this repetition (or --iperf-length). The ceiling is what
//      the iperf3 server received: (packets - lost) / s and received bytes / s.
// Both count datagrams crossing loopback once per second: the relay's ingress plus egress,
// iperf3's one unpaced flow. The ratio says how much of what the kernel's loopback path can
// carry for one sender/receiver pair the relay moves while doing its work. Medians over
// --repeat repetitions. Without iperf3 on PATH the ceiling part is skipped (and said so).
//
// Everything is bounded: connect/join wait <= 10 s, each window as configured, iperf3 under
// `timeout`. The load generator shares the machine with the relay (reported as CPU shares).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

// The members --json echoes under "options" appear there under their own names.
struct CeilingOptions {
  std::vector<size_t> io_threads = {1, 2};
  uint32_t clients = 256;
  uint32_t rooms = 16;
  uint32_t entities_per_client = 4;
  double publish_hz = 120;   // client publish rate (ClientConfig::publish_rate_hz)
  double tick_rate_hz = 120; // relay room tick rate
  double warmup_s = 1.5;
  double duration_s = 4;  // measured window per relay run
  double iperf_seconds = 4;
  uint32_t iperf_length = 0;  // datagram payload bytes; 0: the relay's mean datagram size
  uint16_t iperf_port = 0;    // 0: a free port
  uint32_t repeat = 1;
  bool packet_auth = true;  // the relay under test seals packets (RelayConfig::packet_auth)
  bool progress = true;
  // --relay: the bots load an external edgephys-relay (one --io-threads value: the relay's own
  // flag, echoed); packets, bytes, drops and rejects from its /metrics, relay CPU from
  // /proc/<pid> with --relay-pid (else NaN). Not in --json "options" (see "relay" there).
  ExternalRelayOptions external;
};

// Member names are the --json field names of a "repetitions"[].relay run.
struct CeilingRelayRun {
  size_t io_threads = 1;
  uint32_t clients_joined = 0;
  double seconds = 0;
  double packets_per_s = 0;  // received + sent
  double bytes_per_s = 0;    // received + sent, UDP payload
  double rx_packets_per_s = 0;
  double tx_packets_per_s = 0;
  double mean_datagram_bytes = 0;
  double relay_cpu_cores = 0;  // process CPU minus the bots' thread, per wall second
                               // (external: the relay process's CPU; NaN unknown)
  double bots_cpu_cores = 0;
  uint64_t drops = 0;     // io_queue_drops + send_errors in the window
  uint64_t rejected = 0;  // packets_rejected (all reasons) in the window
};

// Member names are the --json field names of "repetitions"[].iperf3.
struct CeilingIperf {
  bool ran = false;
  std::string error;  // why not, if !ran
  uint32_t length = 0;
  double seconds = 0;
  double sent_packets_per_s = 0;
  double packets_per_s = 0;  // delivered to the iperf3 server
  double bytes_per_s = 0;    // delivered
  double lost_percent = 0;
};

struct CeilingRepetition {
  std::vector<CeilingRelayRun> relay;  // one per io_threads value
  CeilingIperf iperf;
};

struct CeilingSummary {  // medians over repetitions, per io_threads value
  size_t io_threads = 1;
  double packets_per_s = 0, bytes_per_s = 0;
  double iperf_packets_per_s = 0, iperf_bytes_per_s = 0;
  double ratio_packets = 0, ratio_bytes = 0;  // 0 when iperf3 did not run
  double mean_datagram_bytes = 0;
  double relay_cpu_cores = 0, bots_cpu_cores = 0;
  uint64_t drops = 0;
  uint32_t clients_joined = 0;
};

std::vector<CeilingRepetition> RunCeiling(const CeilingOptions& options);
std::vector<CeilingSummary> SummarizeCeiling(const CeilingOptions& options,
                                             const std::vector<CeilingRepetition>& reps);

}  // namespace edgephys::loadgen
