// relay-compare: Decoupled Edge Physics' relay experiment (section 5, "Relay outgoing bandwidth
// vs Photon").
//
// For every mode and object count, in one run: an in-process relay on loopback UDP configured
// with that mode, a host client owning all objects (users of 4: head, two hands, one held
// object) and moving each on a smooth path (motion.h), and N receivers. Measured over a window
// after warm-up: relay egress per receiver (bytes/s, from the relay's per-connection counters
// and from the receiver's socket), entity updates/s per receiver, and the receivers' error
// against the host's truth: for the last received state, against the exact pose the host
// published (max and p99, position in m and rotation in degrees).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "loadgen/motion.h"
#include "loadgen/relay_target.h"
#include "loadgen/emulation/emulation_plugins.h"

namespace edgephys::loadgen {

struct RelayCompareOptions {
  std::vector<uint32_t> objects = {32, 64, 128, 256, 512};
  std::vector<ReplicationMode> modes = {ReplicationMode::kPhoton, ReplicationMode::kPaper,
                                        ReplicationMode::kEdgephys};
  double rate_hz = 12;
  double duration_s = 10;
  double warmup_s = 1.5;
  uint32_t receivers = 2;
  MotionParams motion;
  float position_step_m = 0.001f;
  float rotation_bound_deg = 0.1f;
  float position_threshold_m = 0.0005f;
  float rotation_threshold_deg = 0.05f;
  bool shared_encoding = true;  // edgephys mode: state format 9 (the relay's default); false: 2
  bool progress = true;
  // --relay: an external edgephys-relay (its own format, mode edgephys, with the replication
  // flags it was started with: --position-step, ...; the load generator cannot set them).
  // Egress per receiver then = the /metrics edgephys_bytes_sent_total difference minus what
  // the host's socket received (on loopback, what the relay sent the host), over receivers.
  ExternalRelayOptions external;
};

// Member names are the --json field names of a result.
struct RelayCompareResult {
  ReplicationMode mode;
  uint32_t objects = 0;
  double rate_hz = 0;
  // Bytes are UDP payload as on the wire (sealed datagrams); the IP and UDP headers of the same
  // datagrams are ip_udp_bytes_per_s_per_receiver.
  double egress_bytes_per_s_per_receiver = 0;         // relay's counters (external: /metrics)
  double socket_bytes_per_s_per_receiver = 0;         // receiving socket
  double ip_udp_bytes_per_s_per_receiver = 0;         // kIpUdpHeaderBytes per datagram received
  double updates_per_s_per_receiver = 0;
  double bytes_per_update = 0;
  double pos_err_max_m = 0, pos_err_p99_m = 0;
  double rot_err_max_deg = 0, rot_err_p99_deg = 0;
  double paper_bytes_per_s = 0;                       // Decoupled Edge Physics' column
  uint64_t samples = 0;
};

// Runs every (mode, objects) pair in sequence; returns one result each.
std::vector<RelayCompareResult> RunRelayCompare(const RelayCompareOptions& options);

}  // namespace edgephys::loadgen
