// multiobject: Decoupled Edge Physics' MultiObject scenario (PhyS throughput "Obj_N").
//
// For every object count N, in one run:
//  1. Step time, PhyS vs raw Bullet: the scene of physics/scenes.h (N boxes dropped into
//     a walled container, a kinematic paddle stirring them) built twice from the same
//     parameters and seed — PhysSMultiObjectScene (PhysicsWorld from containers, what the relay
//     runs, including CollectStates/DrainEvents) and RawBulletMultiObjectScene (the baseline) —
//     stepped interleaved (which one goes first alternates), each step timed on its own.
//     After `bench_warmup_steps` of settling, median and p99 of the per-step wall time of each,
//     their ratio, and the share of boxes moving faster than `moving_speed_mps`.
//  2. Replication: an in-process Relay on loopback UDP (embedded PhyS, 60 Hz ticks, edgephys
//     mode, 1 mm / 0.1 deg) and a host client that spawns the same scene as offloaded entities
//     (walls and floor static, boxes Offloaded dynamic bodies) plus the stirrer as an
//     Offloaded|Kinematic body it drives with PublishTransform — mirrored into PhyS, it pushes
//     the boxes. Receivers join the room. Measured over `duration_s` after the pile has had
//     `relay_settle_steps` PhyS steps: relay egress per receiver (its per-connection
//     bytes_sent, Mb/s with 1 Mb = 10^6 bits) beside Decoupled Edge Physics' Obj_N column,
//     entity updates per second, the relay's own mean step time (RelayCounters), PhyS
//     simulated seconds per
//     wall second, the moving share from the states the receiver holds, and the receivers'
//     position error: against the relay's entity state at the same moment (sampled every
//     0.1 s), and against the state the relay had when it sent (best match among the relay's
//     recent states of that entity: quantisation only).
//
// The stirrer's clock is PhyS's simulated time (relay physics steps x dt, read in-process), so
// when PhyS runs slower than real time the paddle slows with it instead of jumping through the
// pile; the same pose function drives the standalone scenes.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "loadgen/loopback_room.h"
#include "loadgen/relay_target.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::loadgen {

// The members --json echoes under "options" appear there under their own names.
struct MultiObjectOptions {
  std::vector<uint32_t> objects = {500, 1000, 2000, 5000, 10000};
  uint32_t seed = 1;
  float stirrer_angular_speed = 1.5f;  // rad/s (MultiObjectParams), both runs
  float stirrer_reach = 0.95f;         // paddle half length / container half width
  float layers = 3.0f;                 // container floor sized for this many layers of boxes
  float stirrer_center_y = 0.4f;       // paddle centre height (m)
  float stirrer_half_height = 0.4f;    // paddle half height (m); 0.4 at 0.4 spans the pile
  float sleep_threshold = 0.1f;        // PhyS sleeping thresholds, m/s and rad/s (raw Bullet: 0.8/1.0)
  bool rest_freeze = true;             // PhysicsConfig::rest_freeze (resting regions)
  double moving_speed_mps = 0.01;  // "moving": linear speed above this
  // Standalone PhyS vs raw Bullet.
  bool bench = true;
  int bench_warmup_steps = 120;    // settling (2 s simulated), not measured
  int bench_steps = 300;           // measured steps per scene, at most...
  double bench_max_s = 25;         // ...and at most this wall time for both scenes together
  int bench_min_steps = 30;        // ...but at least this many
  // Relay.
  bool relay = true;
  // --relay/--secret/--metrics/--relay-pid: run the relay part against an external
  // edgephys-relay (multiobject_external.cc) instead of an in-process one. The scene, the host
  // and the receivers are the same; the relay's own options (ambient rate, thresholds,
  // substeps, sleeping) are its command line's, not these; server-side figures come
  // from its /metrics, and what needs its entity table (errors against its truth, the display
  // probe) is unknown (JSON null).
  ExternalRelayOptions external;
  uint32_t receivers = 2;
  double duration_s = 5;           // measured wall seconds
  int relay_settle_steps = 120;    // PhyS steps after the spawns before measuring
  double relay_settle_max_s = 45;  // wall cap for settling
  int relay_max_substeps = 1;      // PhysicsConfig::max_substeps of the relay's PhyS
  float position_step_m = 0.001f;
  float rotation_bound_deg = 0.1f;
  // Selective-sync thresholds (ReplicationConfig); negative: the relay's defaults.
  float position_threshold_m = -1.f;
  float rotation_threshold_deg = -1.f;
  // ReplicationConfig::ambient_hz (boxes nobody touches); <= 0: the relay's default.
  double ambient_hz = 0;
  // ReplicationConfig::shared_encoding: state format 9 (the relay's default); false: format 2.
  bool shared_encoding = true;
  // >= 0: the probe plays out at this fixed delay (s); < 0: the SDK's adaptive delay.
  double playout_min_delay_s = -1;
  // > 0: the probe's third yardstick (display_err_adaptive_*) plays the room out held to this
  // delay (s), as an SDK application under edgephys_client_set_max_playout_delay; else the
  // adaptive delay alone.
  double playout_limit_s = 0;
  bool progress = true;
};

struct MultiObjectResult {
  uint32_t objects = 0;
  // Standalone, same run, interleaved.
  double step_ms_median = 0, step_ms_p99 = 0;                        // PhyS (PhysicsWorld)
  double raw_bullet_step_ms_median = 0, raw_bullet_step_ms_p99 = 0;  // raw Bullet
  double step_ratio = 0;             // PhyS median / raw Bullet median
  int bench_steps = 0;               // measured steps per scene
  double moving_fraction = 0, moving_fraction_min = 0;          // PhyS scene, sampled
  double raw_moving_fraction = 0, raw_moving_fraction_min = 0;  // raw Bullet scene
  // Relay run.
  bool relay_ok = false;
  double egress_mbit_per_s_per_client = 0;  // relay's counters, mean over receivers
  double socket_mbit_per_s_per_client = 0;  // receiving sockets
  // The IP and UDP headers of the datagrams received, beside the UDP payload figures above
  // (which count the sealed datagrams); unknown against an external relay.
  double ip_udp_mbit_per_s_per_client = 0;
  double paper_mbit_per_s = 0;              // Decoupled Edge Physics' Obj_N (0: none)
  double updates_per_s_per_client = 0;
  double bytes_per_update = 0;              // all egress bytes / entity updates
  double state_mbit_per_s_per_client = 0;   // state payload bytes only (Client::state_bytes_received)
  double events_per_s_per_client = 0;       // physics events received (reliable channel)
  double relay_step_ms_mean = 0;            // RelayCounters::physics_step_seconds
  double sim_speed = 0;                     // PhyS simulated seconds per wall second
  double relay_moving_fraction = 0, relay_moving_fraction_min = 0;  // from received states
  double pos_err_max_m = 0, pos_err_p99_m = 0;            // vs relay state, same moment
  double pos_err_sent_max_m = 0, pos_err_sent_p99_m = 0;  // vs the relay state it was sent from
  uint64_t error_samples = 0;
  // What receiver 0 displays (jitter buffer + interpolation, up to 128 boxes sampled every
  // 50 ms) against the relay's state at the displayed relay time: lerp+slerp and Hermite.
  double display_err_p50_m = 0, display_err_p99_m = 0;
  double display_rot_err_p50_deg = 0, display_rot_err_p99_deg = 0;  // the displayed method's
  double display_err_hermite_p50_m = 0, display_err_hermite_p99_m = 0;
  // The displayed pose against the truth at the time PhyS computed it for (Entity::state_time)
  // rather than at the time the relay got it: includes the step's computation latency.
  double display_err_state_p50_m = 0, display_err_state_p99_m = 0;
  // The same arrivals played out held to playout_limit_s (the same as display_err_* without
  // one), same method.
  double display_err_adaptive_p50_m = 0, display_err_adaptive_p99_m = 0;
  double display_adaptive_playout_ms_median = 0;
  double display_delay_ms_median = 0;  // playout delay behind the newest received state
  double display_playout_ms_median = 0;  // render time behind the estimated relay now
  uint64_t display_samples = 0;
  double spawn_s = 0;                       // wall time to spawn the scene everywhere
  double external_cpu_cores = kUnknown;     // external relay: its CPU (needs --relay-pid)
};

std::vector<MultiObjectResult> RunMultiObject(const MultiObjectOptions& options);

// The scene of both runs for `objects` boxes: container, boxes and stirrer from the options.
physics::MultiObjectParams MultiObjectSceneParams(const MultiObjectOptions& options, uint32_t objects);

// The relay part of one size against options.external (multiobject_external.cc).
void ExternalMultiObjectRun(const MultiObjectOptions& options, uint32_t objects,
                            MultiObjectResult* result);

}  // namespace edgephys::loadgen
