// softbody: Decoupled Edge Physics' Softbody scenario (PhyS throughput "Bunny_1", "Bunny_3").
//
// For every bunny count N, in one run:
//  1. Step time: a standalone PhysicsWorld with the scene (a static floor, N bunny soft bodies
//     of ~`particles` particles each from physics::MakeBunnySoftBody dropped onto it, and one
//     kinematic sphere "hand" per bunny; once the bunnies have landed each hand is aimed at its
//     bunny's centroid and pokes down to 40% of the body's thickness there every period,
//     phases staggered), stepped as the relay steps it (hand
//     moves, Step, CollectStates, DrainEvents, GetSoftBodyNodes of the moved soft bodies); per
//     step wall time, median and p99, after `bench_warmup_steps` of settling.
//  2. Replication: an in-process Relay on loopback UDP (embedded PhyS, 60 Hz ticks, edgephys
//     mode, 1 mm particle step) and a host client that spawns the floor and the bunnies as
//     offloaded entities (PhyS simulates the bunnies) and the hands as Offloaded|Hand|Kinematic
//     bodies it drives with PublishTransform (mirrored into PhyS, they push the bunnies).
//     Receivers join the room. Measured over `duration_s`: relay egress per receiver (Mb/s,
//     10^6 bits) beside Decoupled Edge Physics' Bunny_N, soft-body updates received per second, the
//     relay's mean PhyS step time, simulated seconds per wall second, bunny 0's deformation
//     (largest change of a spring's length from rest; its spread shows that the hands poke),
//     and the receivers' particle error: against the relay's particles at the same moment
//     (sampled every 0.1 s), and against the particles the relay sent (per particle, the best
//     match among the relay's recent versions: quantisation only).
// The hands' clock is PhyS's simulated time (relay physics steps x dt, read in-process).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

// The members --json echoes under "options" appear there under their own names.
struct SoftBodyOptions {
  std::vector<uint32_t> bunnies = {1, 3};
  int particles = 500;             // target per bunny (MakeBunnySoftBody: within ~10%)
  double poke_period_s = 1.5;      // one poke (down and up) per period, phases staggered
  // Standalone step time.
  int bench_warmup_steps = 90;
  int bench_steps = 300;
  double bench_max_s = 20;
  // Relay.
  uint32_t receivers = 2;
  double duration_s = 5;
  int relay_settle_steps = 90;     // PhyS steps after the spawns before measuring
  double relay_settle_max_s = 30;
  float position_step_m = 0.001f;
  float rotation_bound_deg = 0.1f;
  // --relay/--secret/--metrics/--relay-pid: the relay part against an external edgephys-relay
  // (softbody_external.cc); its replication and PhyS settings are its own flags. Particle
  // errors against the relay's particles are then unknown (null).
  ExternalRelayOptions external;
  double soft_touched_hz = 0;      // > 0: the relay's ReplicationConfig::soft_touched_hz
  bool progress = true;
};

// Member names are the --json field names of a result.
struct SoftBodyResult {
  uint32_t bunnies = 0;
  uint32_t particles = 0;                   // all bunnies
  double step_ms_median = 0, step_ms_p99 = 0;  // standalone PhysicsWorld
  int bench_steps = 0;
  bool relay_ok = false;
  double egress_mbit_per_s_per_client = 0;  // relay's counters, mean over receivers
  double socket_mbit_per_s_per_client = 0;
  double ip_udp_mbit_per_s_per_client = 0;  // IP+UDP headers beside it; unknown when external
  double paper_mbit_per_s = 0;              // Bunny_1 / Bunny_3 (0: not in Decoupled Edge Physics)
  double soft_updates_per_s_per_client = 0; // OnSoftBodyUpdated (one per chunk)
  double relay_step_ms_mean = 0;
  double sim_speed = 0;
  // Bunny 0 at the relay: largest change of a spring's length from rest (m), min and max of
  // that over the window (poking shows as the spread).
  double deformation_min_m = 0, deformation_max_m = 0;
  double node_err_max_m = 0, node_err_p99_m = 0;        // vs relay particles, same moment
  double node_err_sent_max_m = 0, node_err_sent_p99_m = 0;  // vs the particles the relay sent
  uint64_t error_samples = 0;
};

std::vector<SoftBodyResult> RunSoftBody(const SoftBodyOptions& options);
// The relay part of one size against options.external (softbody_external.cc).
void ExternalSoftBodyRun(const SoftBodyOptions& options, uint32_t bunnies, SoftBodyResult* result);

}  // namespace edgephys::loadgen
