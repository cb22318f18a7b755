// isolation: does a heavy PhyS room slow down a busy social room on the same relay?
//
// Room A: --users ccu-style bots (a head and two hands each, the hands with trigger spheres
// mirrored into PhyS, poses published at --publish-hz), every bot watching every other bot's
// right hand. Room B: the multiobject scene (physics/scenes.h: --boxes boxes in a walled
// container, a kinematic stirrer) spawned as Offloaded entities by one host client, which drives
// the stirrer (on wall-clock time since B started, so the same in-process and external), plus
// --b-receivers receivers. A's bots run on the calling thread; B's clients on a second thread,
// so decoding B's states does not delay A's bots.
//
// One run, three phases (each --phase seconds, after A's ramp):
//   alone   A only;
//   with_b  B's host joins and spawns the scene, B's receivers join; once every spawn is sent
//           and --late-join-delay has passed, a late joiner joins room B and the time until it
//           has received every one of the scene's spawns is measured (the phase lasts until it
//           has, at most --late-join-timeout after it joined, and at least --phase);
//   after   (unless --no-after) B's clients disconnect; A alone again (the relay may keep the
//           empty room, and its PhyS world, until its idle TTL).
// Per phase: A's right-hand latency user to user (p50/p99) at the SDK (the receiving bot's
// callback, steady clock) and at the socket (kernel receive timestamp, CLOCK_REALTIME), the
// fraction of expected hand updates delivered, the bot pass, and the relay's figures over the
// phase (egress, ingress, relay CPU, PhyS step time). Headline: A's p99 with B / A's p99 alone.
// A latency series in --bin-s bins for the chart.
//
// The relay is started in-process (its own thread, --physics-threads, --tick-rate) or is an
// external edgephys-relay (--relay, --secret, --metrics, --relay-pid; loadgen/relay_target.h).
//
// Controls, to tell the causes of A's rise apart:
//   --b-mode burn   no room B: for the with_b phase, an unrelated process (this binary's
//                   `physics-burn`, below) steps the same scene back to back at
//                   niceness --burn-nice, then is stopped by its PID. What is left of A's rise
//                   is the machine (cores, caches, memory), not the relay or the load generator.
//   --b-decode joiner   B's host and receivers acknowledge B's states without decoding them
//                   (ClientConfig::decode_states; the relay does the same work for them); the
//                   late joiner still decodes. Takes B's decoding off the load generator's CPU.
//   --b-thread-nice N   B's clients' thread runs at niceness N, below A's bots.
//   --b-thread-idle     B's clients' thread runs under SCHED_IDLE: only on a core A's bots and
//                   the relay leave idle. B's clients stand for users on other machines, so
//                   their CPU here is the load generator's, not the relay's; B's late joiner
//                   still has to receive B's scene in time.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string>
#include <vector>

#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

struct IsolationOptions {
  uint32_t users = 50;
  uint32_t boxes = 10000;
  uint32_t b_receivers = 1;
  double ramp_s = 3;                 // A's bots join over this
  double phase_s = 10;               // each phase
  bool after_phase = true;
  double late_join_delay_s = 1;      // after B's spawns are all sent
  double late_join_timeout_s = 60;   // the late joiner's wait, at most
  double tick_rate_hz = 60;          // in-process relay
  double publish_hz = 30;            // A's pose updates (ccu's rate)
  size_t physics_threads = 1;        // in-process relay (RelayConfig::physics_threads)
  int physics_nice = -1;             // in-process relay: RelayConfig::physics_nice (-1: its default)
  bool physics_idle = false;         // in-process relay: RelayConfig::physics_idle
  double bin_s = 0.5;                // latency series bins
  uint32_t measure_every = 1;        // only every K-th A bot matches poses (all decode)
  uint32_t seed = 1;
  bool progress = true;
  bool b_burn = false;               // --b-mode burn: a physics-burn process instead of room B
  int burn_nice = 0;                 // its niceness
  bool b_decode = true;              // B's host and receivers decode states (the joiner always)
  int b_thread_nice = 0;             // niceness of B's clients' thread
  bool b_thread_idle = false;        // B's clients' thread under SCHED_IDLE
  ExternalRelayOptions external;
};

struct IsolationPhase {
  std::string name;                  // alone, with_b, after
  double start_s = 0, end_s = 0;
  uint64_t samples = 0;
  double latency_ms_p50 = 0, latency_ms_p99 = 0;                  // SDK
  double arrival_latency_ms_p50 = 0, arrival_latency_ms_p99 = 0;  // socket
  double delivered_fraction = 0;     // hand updates received / expected
  double bot_pass_ms_p99 = 0;
  // Relay, over the phase (NaN: unknown, e.g. CPU of an external relay without --relay-pid).
  bool relay_figures = false;
  double egress_bytes_per_s = 0, ingress_bytes_per_s = 0;
  double relay_cpu = 0;              // cores
  double physics_step_ms_mean = 0;
  double physics_steps_per_s = 0;
};

struct IsolationBin {
  double t = 0;  // bin start
  uint64_t samples = 0;
  double latency_ms_p50 = 0, latency_ms_p99 = 0;
  double arrival_latency_ms_p50 = 0, arrival_latency_ms_p99 = 0;
};

struct IsolationResult {
  uint32_t users = 0, connected = 0;
  uint32_t boxes = 0;
  bool b_ok = false;                  // B's host joined and spawned its scene (burn: ran)
  // --b-mode burn: the burner's figures (from its JSON); 0 otherwise.
  uint64_t burn_steps = 0;
  double burn_step_ms_mean = 0;
  std::string b_error;
  double b_spawn_send_s = 0;          // B's host: time to issue every Spawn
  std::string b_thread_policy;        // scheduling policy B's clients' thread ran under
  bool late_join_ok = false;
  double late_join_s = kUnknown;      // late joiner's join request -> every spawn received
  uint32_t late_join_spawns = 0;      // spawns it received (of scene_entities)
  uint32_t scene_entities = 0;
  double p99_ratio = kUnknown;        // A's SDK p99 with B / alone
  double arrival_p99_ratio = kUnknown;
  std::vector<IsolationPhase> phases;
  std::vector<IsolationBin> bins;
  uint32_t metrics_failures = 0;
  std::string metrics_error;
};

IsolationResult RunIsolation(const IsolationOptions& options);

// physics-burn: a control for `isolation`. Steps the multiobject scene (physics/scenes.h, the
// scene room B offloads to the relay's PhyS) back to back, as fast as one thread can, in a
// process of its own that is not the relay: the CPU and memory load of B's physics thread
// without any relay work. `isolation --b-mode burn` starts it for its with_b phase.
//
// Runs until `seconds` have passed or SIGTERM / SIGINT arrives (checked between steps, so it
// ends within one step: ~60 ms at 10,000 boxes). `nice`: added to this process's niceness
// first (0..19), as --physics-nice does for the relay's physics threads.
struct PhysicsBurnOptions {
  uint32_t boxes = 10000;
  double seconds = 30;
  int nice = 0;
  uint32_t seed = 1;
};

struct PhysicsBurnResult {
  uint64_t steps = 0;
  double seconds = 0;
  double step_ms_mean = 0;
  int niceness = 0;  // the process's niceness while stepping (getpriority)
};

// In this process (the `physics-burn` subcommand).
PhysicsBurnResult RunPhysicsBurn(const PhysicsBurnOptions& options);

// `physics-burn` as a child process of this binary (/proc/self/exe), its stdout to /dev/null,
// its figures to a JSON file in /tmp; stopped by its PID. Not thread-safe; one run at a time.
class PhysicsBurnProcess {
 public:
  PhysicsBurnProcess() = default;
  ~PhysicsBurnProcess();  // stops a running child
  PhysicsBurnProcess(const PhysicsBurnProcess&) = delete;
  PhysicsBurnProcess& operator=(const PhysicsBurnProcess&) = delete;
  // false (with *error) if it cannot be started or one is running already.
  bool Start(const PhysicsBurnOptions& options, std::string* error);
  // SIGTERM, waits for it (at most 10 s, then SIGKILL) and reads its figures into *result
  // (may be null). false (with *error, may be null) if none ran, it did not exit 0 by itself,
  // or wrote no figures.
  bool Stop(PhysicsBurnResult* result = nullptr, std::string* error = nullptr);
  bool running() const { return pid_ > 0; }

 private:
  pid_t pid_ = -1;
  std::string json_path_;
};

}  // namespace edgephys::loadgen
