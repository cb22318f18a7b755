// hostile: what one hostile player does to honest players, in its own room and in another, on
// a relay with its default limits (issue 14, "Hardening").
//
// For each attack class of the issue (loadgen/hostile_attacks.h: physics, names, churn, flood,
// forged, invalid) the run builds two fresh rooms, A (the attacker's) and B (another), each with
// --honest honest clients that spawn one entity each and publish its pose at --publish-hz. A
// pose carries a sequence number in its position (a 2 cm lattice, far above the codec's 1 mm
// step), so a receiver counts every distinct update of every other honest member and knows when
// it was published (same process, same steady clock): received updates per second and per
// sender, p50/p99 latency publish -> receiver's callback, and the longest gap between two
// updates of one sender. Two phases of --phase seconds each:
//   baseline  the attacker is connected (where its attack needs it) and idle;
//   attack    the attacker attacks; the phase lasts --phase after the attack has run its
//             course (everything sent and answered: physics, names; the others at once), at
//             most --attack-max after its start.
// In each phase, halfway, a late joiner (the probe) connects to room A from the honest address
// and joins: its time to Joined and to holding every entity an honest member of A holds.
// The relay's refusal counters with their reason labels (edgephys_budget_refusals_total,
// _requests_rejected_total, _packets_rejected_total, _entity_updates_rejected_total,
// _disconnects_total) are read from its Prometheus /metrics at each phase boundary; the attack's
// refusals are the differences over the attack phase. An in-process relay (the default) gets a
// MetricsExporter of its own on an ephemeral loopback port, so both paths read the same text.
//
// Threads: the honest clients (both rooms and the probe) on one thread, the attacker on the
// calling thread, the in-process relay on its own (plus its PhyS threads).
// Addresses: with a relay on IPv4 loopback the honest clients use 127.0.0.1, the attacker
// 127.0.2.1 and the handshake flood --flood-address (default 127.0.16.1), so per-address limits
// apply to each as they would to separate hosts. A relay elsewhere: every client binds the
// wildcard address and the flood is skipped.
// Bounds: every wait is bounded; the whole run lasts about attacks x (2 x --phase + 4) seconds.
#pragma once

#include <cstdint>
#include <map>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "loadgen/relay_target.h"

namespace edgephys::loadgen {

struct HostileOptions {
  std::vector<std::string> attacks;  // loadgen/hostile_attacks.h names, in order
  uint32_t honest = 3;               // honest clients per room
  double phase_s = 4;                // baseline and attack, each
  double attack_max_s = 40;          // an attack that has not run its course by then is cut
  double publish_hz = 60;            // honest poses per second
  // Attack sizes (the figures by default).
  uint32_t soft_bodies = 20;
  uint32_t particles = 4096;         // target particles per soft body (the bunny lattice)
  uint32_t huge_names = 18;
  uint32_t name_bytes = 500000;
  double flood_rate = 10000;         // handshake datagrams per second
  std::string flood_address = "127.0.16.1";
  // In-process relay.
  size_t physics_threads = 0;        // 0: RelayConfig's default
  double tick_rate_hz = 60;
  bool progress = true;
  ExternalRelayOptions external;
};

// What the honest clients of one room received over one phase.
struct HonestRoomFigures {
  uint32_t members = 0, connected = 0;  // at the phase's end
  uint64_t updates = 0;                 // distinct updates received, all pairs
  double rate = 0;                      // updates/s per (receiver, sender) pair, mean
  double min_pair_rate = 0;
  double latency_ms_p50 = 0, latency_ms_p99 = 0;
  double max_gap_s = 0;                 // longest wait for a sender's next update, any pair
};

struct ProbeFigures {
  bool started = false, joined = false, complete = false;
  double join_ms = 0;    // Connect -> Joined
  double state_ms = 0;   // Connect -> holds every entity an honest member of A held at start
  uint32_t entities = 0, target = 0;
  std::string failure;   // rejected, disconnected (with the reason), timed out
};

struct HostilePhase {
  std::string name;  // baseline, attack
  double seconds = 0;
  HonestRoomFigures same, other;  // room A (the attacker's), room B
  ProbeFigures probe;
  // Refusal counters that moved over the phase: "budget_refusals{player_particles}" -> count.
  std::map<std::string, double> refusals;
  double physics_step_ms_mean = kUnknown;
  double entities_gauge_end = kUnknown;  // edgephys_entities at the phase's end
};

struct HostileAttackResult {
  std::string attack;
  std::string description;
  bool ran = false;
  std::string error;  // why it did not run or what went wrong
  HostilePhase baseline, attack_phase;
  double same_ratio = kUnknown, other_ratio = kUnknown;  // attack rate / baseline rate
  double attack_done_s = 0;  // when the attack had run its course, from the phase's start
  nlohmann::json notes;  // the attacker's own view (sent, refused with reasons, ...)
};

struct HostileResult {
  std::vector<HostileAttackResult> attacks;
  std::string metrics;        // where the refusal counters came from
  std::string metrics_error;  // the last failed scrape, if any
};

HostileResult RunHostile(const HostileOptions& options);

}  // namespace edgephys::loadgen
