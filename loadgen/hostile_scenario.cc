// hostile as a Scenario: options, validation and the report (JSON and table).
#include <CLI/CLI.hpp>
#include <cmath>
#include <sstream>

#include "loadgen/hostile.h"
#include "loadgen/hostile_attacks.h"
#include "loadgen/scenario.h"

namespace edgephys::loadgen {

// NaN becomes JSON null (nlohmann::json writes non-finite numbers as null).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(HonestRoomFigures, members, connected, updates, rate,
                                   min_pair_rate, latency_ms_p50, latency_ms_p99, max_gap_s)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(ProbeFigures, started, joined, complete, join_ms, state_ms,
                                   entities, target, failure)
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(HostilePhase, name, seconds, same, other, probe, refusals,
                                   physics_step_ms_mean, entities_gauge_end)
// The options a report echoes, named as the members (the in-process relay's added).
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(HostileOptions, attacks, honest, attack_max_s, phase_s,
                                   publish_hz, soft_bodies, particles, huge_names, name_bytes,
                                   flood_rate, flood_address)

namespace {

nlohmann::json Json(const HostileOptions& o, const HostileResult& r) {
  nlohmann::json j = {{"options", o}};
  if (o.external.enabled()) {
    j["relay"] = {{"external", true}, {"address", o.external.relay}};
  } else {
    j["options"]["tick_rate_hz"] = o.tick_rate_hz;
    j["options"]["physics_threads"] = o.physics_threads;
    j["relay"] = {{"external", false}, {"config", "RelayConfig defaults (limits, budgets, packet auth)"}};
  }
  j["metrics"] = r.metrics;
  if (!r.metrics_error.empty()) j["metrics_error"] = r.metrics_error;
  j["notes"] = {
      {"rate", "distinct pose updates received per second per (receiver, sender) pair of honest "
               "members of one room, mean over the pairs; ratio = attack / baseline"},
      {"same, other", "room A (the attacker's) and room B (another room)"},
      {"refusals", "differences of the relay's edgephys_*{reason} refusal counters over the "
                   "phase (process-wide; disconnects by the client's own leave left out)"},
      {"probe", "a late joiner of room A halfway through the phase: Connect -> Joined, and -> "
                "holding every entity an honest member held"}};
  nlohmann::json attacks = nlohmann::json::array();
  for (const HostileAttackResult& a : r.attacks) {
    nlohmann::json x = {{"attack", a.attack}, {"description", a.description}, {"ran", a.ran}};
    if (!a.error.empty()) x["error"] = a.error;
    if (a.ran) {
      x["baseline"] = a.baseline;
      x["attack_phase"] = a.attack_phase;
      x["attack_done_s"] = a.attack_done_s;
      x["same_room_rate_ratio"] = a.same_ratio;
      x["other_room_rate_ratio"] = a.other_ratio;
      x["attacker"] = a.notes;
    }
    attacks.push_back(std::move(x));
  }
  j["attacks"] = std::move(attacks);
  return j;
}

std::string Refusals(const std::map<std::string, double>& refusals) {
  std::ostringstream s;
  for (const auto& [name, count] : refusals) {
    if (s.tellp() > 0) s << " ";
    s << name << "=" << static_cast<unsigned long long>(count);
  }
  return s.tellp() > 0 ? s.str() : "-";
}

void FillTable(const HostileOptions& o, const HostileResult& r, Table* t) {
  t->Line("hostile: %u honest clients in the attacker's room A and in room B, poses at %.0f Hz; "
          "refusals from %s\n", o.honest, o.publish_hz, r.metrics.c_str());
  t->Line("%-8s %-21s %-21s %-15s %-15s %-15s\n", "attack", "A upd/s base>att", "B upd/s base>att",
          "A p50/p99 ms", "B p50/p99 ms", "join ms b/a");
  for (const HostileAttackResult& a : r.attacks) {
    if (!a.ran) {
      t->Line("%-8s not run: %s\n", a.attack.c_str(), a.error.c_str());
      continue;
    }
    const HostilePhase& b = a.baseline;
    const HostilePhase& x = a.attack_phase;
    char same[32], other[32], lat_a[32], lat_b[32], join[40];
    std::snprintf(same, sizeof same, "%.1f>%.1f (%.2f)", b.same.rate, x.same.rate, a.same_ratio);
    std::snprintf(other, sizeof other, "%.1f>%.1f (%.2f)", b.other.rate, x.other.rate, a.other_ratio);
    std::snprintf(lat_a, sizeof lat_a, "%.0f/%.0f", x.same.latency_ms_p50, x.same.latency_ms_p99);
    std::snprintf(lat_b, sizeof lat_b, "%.0f/%.0f", x.other.latency_ms_p50, x.other.latency_ms_p99);
    auto probe = [](const ProbeFigures& p) {
      return p.complete ? std::to_string(static_cast<long>(std::lround(p.state_ms))) : std::string("FAIL");
    };
    std::snprintf(join, sizeof join, "%s/%s", probe(b.probe).c_str(), probe(x.probe).c_str());
    t->Line("%-8s %-21s %-21s %-15s %-15s %-15s\n", a.attack.c_str(), same, other, lat_a, lat_b, join);
    t->Line("         %.1f s (done at %.1f s); honest connected A %u/%u B %u/%u; max gap A %.2f s B %.2f s; "
            "refused: %s\n", x.seconds, a.attack_done_s, x.same.connected, x.same.members, x.other.connected,
            x.other.members, x.same.max_gap_s, x.other.max_gap_s, Refusals(x.refusals).c_str());
  }
  t->Text("(upd/s: updates received per second per sender, baseline > attack (ratio); latencies "
          "in the attack phase; join ms: a late joiner of A until it held the room's entities, "
          "baseline/attack)\n");
}

class HostileScenario final : public MeasuringScenario<HostileOptions, HostileResult> {
 public:
  HostileScenario()
      : MeasuringScenario("hostile",
                          "One hostile player per attack class of issue 14; honest clients' update "
                          "rate in its room and another, and the relay's refusals by reason",
                          {Json, FillTable}) {}

  void AddOptions(CLI::App& cmd) override {
    std::string names;
    for (const HostileAttackInfo& a : HostileAttacks()) names += std::string(names.empty() ? "" : ",") + a.name;
    attacks_ = names;
    cmd.add_option("--attacks", attacks_, "Attacks to run, in order (" + names + ")");
    cmd.add_option("--honest", o_.honest, "Honest clients per room (at least 2)");
    cmd.add_option("--phase", o_.phase_s, "Seconds of the baseline and of the attack phase");
    cmd.add_option("--attack-max", o_.attack_max_s,
                   "Seconds after which an attack still sending is taken as done");
    cmd.add_option("--publish-hz", o_.publish_hz, "Honest pose updates per second");
    cmd.add_option("--soft-bodies", o_.soft_bodies, "physics: offloaded soft bodies");
    cmd.add_option("--particles", o_.particles, "physics: particles per soft body (target)");
    cmd.add_option("--huge-names", o_.huge_names, "names: entities with huge names");
    cmd.add_option("--name-bytes", o_.name_bytes, "names: bytes per huge name");
    cmd.add_option("--flood-rate", o_.flood_rate, "flood: handshake datagrams per second");
    cmd.add_option("--flood-address", o_.flood_address, "flood: the loopback address it comes from");
    cmd.add_option("--tick-rate", o_.tick_rate_hz, "In-process relay: room tick rate");
    cmd.add_option("--physics-threads", o_.physics_threads,
                   "In-process relay: RelayConfig::physics_threads (0: its default)");
    AddExternalRelayOptions(cmd, &o_.external);
  }

  std::string Validate() override {
    std::string unknown;
    if (!ParseNames(attacks_, [](const std::string& n, std::string* out) {
          *out = n;
          return FindHostileAttack(n) != nullptr;
        }, &o_.attacks, &unknown)) {
      return "--attacks: unknown attack " + unknown;
    }
    if (o_.attacks.empty()) return "--attacks: none given";
    if (o_.honest < 2 || o_.honest > 50) return "--honest must be 2 .. 50";
    if (!(o_.phase_s > 0 && o_.phase_s <= 120)) return "--phase must be in (0, 120]";
    if (!(o_.attack_max_s > 0 && o_.attack_max_s <= 600)) return "--attack-max must be in (0, 600]";
    if (!(o_.publish_hz > 0 && o_.publish_hz <= 240)) return "--publish-hz must be in (0, 240]";
    if (o_.soft_bodies > 1000 || o_.particles == 0 || o_.particles > 65536) {
      return "--soft-bodies at most 1000, --particles 1 .. 65536";
    }
    if (o_.huge_names > 1000 || o_.name_bytes > (4u << 20)) return "--huge-names at most 1000, --name-bytes at most 4 MiB";
    if (!(o_.flood_rate > 0 && o_.flood_rate <= 1e6)) return "--flood-rate must be in (0, 1e6]";
    return ValidateExternalRelay(o_.external);
  }

  std::optional<HostileResult> Measure() override { return RunHostile(o_); }

  bool Succeeded(const HostileResult& r) const override {
    bool ok = r.metrics_error.empty();
    for (const HostileAttackResult& a : r.attacks) {
      ok = ok && (a.ran || a.error.rfind("skipped", 0) == 0);
    }
    return ok;
  }

 private:
  std::string attacks_;
};

}  // namespace

std::unique_ptr<Scenario> MakeHostileScenario() { return std::make_unique<HostileScenario>(); }

}  // namespace edgephys::loadgen
