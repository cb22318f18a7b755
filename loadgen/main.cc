// edgephys-loadgen: bot users and the paper's scenarios against edgephys and its emulated
// baselines. Every scenario writes --json FILE, prints a table and writes gnuplot charts.
//
//   edgephys-loadgen relay-compare --objects 32,64,128,256,512 --modes photon,paper,edgephys
//   edgephys-loadgen interp-sweep --rates 6,12,24,30,48,60 --interpolators lerp-slerp,hermite
//   edgephys-loadgen codec-sweep --steps 0.0005,0.001,0.002,0.005 --thresholds 0,0.0005
//   edgephys-loadgen multiobject --objects 500,1000,2000,5000,10000
//   edgephys-loadgen softbody --bunnies 1,3
//   edgephys-loadgen ceiling --io-threads 1,2 --repeat 3 --json ceiling.json
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>
#include <sstream>

#include "loadgen/codec_sweep.h"
#include "loadgen/interp_sweep.h"
#include "loadgen/multiobject.h"
#include "loadgen/ccu.h"
#include "loadgen/ceiling.h"
#include "loadgen/relay_compare.h"
#include "loadgen/report.h"
#include "loadgen/softbody.h"

namespace {

template <typename T>
bool ParseList(const std::string& text, std::vector<T>* out) {
  out->clear();
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    std::stringstream is(item);
    T v;
    if (!(is >> v)) return false;
    out->push_back(v);
  }
  return !out->empty();
}

}  // namespace

int main(int argc, char** argv) {
  using namespace edgephys;
  using namespace edgephys::loadgen;
  CLI::App app{"edgephys-loadgen: load generator and benchmark scenarios"};
  app.require_subcommand(1);
  spdlog::set_level(spdlog::level::warn);

  auto* rc = app.add_subcommand("relay-compare", "The paper's relay bandwidth experiment");
  RelayCompareOptions o;
  std::string objects = "32,64,128,256,512", modes = "photon,paper,edgephys";
  std::string json_path, chart_prefix = "relay_compare";
  rc->add_option("--objects", objects, "Object counts (comma separated)")->capture_default_str();
  rc->add_option("--modes", modes, "Modes: photon,paper,edgephys,float")->capture_default_str();
  rc->add_option("--rate", o.rate_hz, "Sends per second per object")->capture_default_str();
  rc->add_option("--duration", o.duration_s, "Measured seconds per mode and size")->capture_default_str();
  rc->add_option("--warmup", o.warmup_s, "Seconds before measuring")->capture_default_str();
  rc->add_option("--receivers", o.receivers, "Receiving clients")->capture_default_str();
  rc->add_option("--speed", o.motion.speed_mps, "Object speed (m/s)")->capture_default_str();
  rc->add_option("--spin", o.motion.spin_dps, "Object spin (deg/s)")->capture_default_str();
  rc->add_option("--seed", o.motion.seed, "Motion seed")->capture_default_str();
  rc->add_option("--position-step", o.position_step_m, "edgephys quantisation step (m)")->capture_default_str();
  rc->add_option("--rotation-bound", o.rotation_bound_deg, "edgephys rotation bound (deg)")->capture_default_str();
  rc->add_option("--position-threshold", o.position_threshold_m, "Selective sync threshold (m)")->capture_default_str();
  rc->add_option("--rotation-threshold", o.rotation_threshold_deg, "Selective sync threshold (deg)")->capture_default_str();
  rc->add_option("--json", json_path, "Write results as JSON to this file");
  rc->add_option("--charts", chart_prefix, "Chart file prefix ('' for none)")->capture_default_str();
  rc->add_flag("!--no-progress", o.progress, "Hide the progress line");

  // interp-sweep: client smoothing error vs send rate (offline).
  auto* is = app.add_subcommand("interp-sweep", "Interpolation error vs send rate (offline)");
  InterpSweepOptions io;
  std::string interp_rates = "6,12,24,30,48,60";
  std::string interp_methods = "lerp-slerp,dq-dlb,dq-sclerp,hermite,none";
  std::string interp_json, interp_charts = "interp_sweep";
  double impaired_latency_s = 0.030, impaired_jitter_s = 0.020, impaired_loss = 0.05;
  is->add_option("--rates", interp_rates, "Send rates in Hz (comma separated)")->capture_default_str();
  is->add_option("--interpolators", interp_methods,
                 "lerp-slerp,dq-dlb,dq-sclerp,hermite,none")->capture_default_str();
  is->add_option("--duration", io.duration_s, "Measured seconds per rate and network")->capture_default_str();
  is->add_option("--warmup", io.warmup_s, "Rendered but unmeasured seconds first")->capture_default_str();
  is->add_option("--objects", io.objects, "Objects (independent streams)")->capture_default_str();
  is->add_option("--render-hz", io.render_hz, "Receiver frame rate")->capture_default_str();
  is->add_option("--speed", io.motion.speed_mps, "Object speed (m/s)")->capture_default_str();
  is->add_option("--spin", io.motion.spin_dps, "Object spin (deg/s)")->capture_default_str();
  is->add_option("--seed", io.motion.seed, "Motion and network seed")->capture_default_str();
  is->add_option("--latency", impaired_latency_s, "Base one-way latency (s), both conditions")->capture_default_str();
  is->add_option("--jitter", impaired_jitter_s, "Impaired condition: uniform +- jitter (s)")->capture_default_str();
  is->add_option("--loss", impaired_loss, "Impaired condition: loss probability")->capture_default_str();
  is->add_flag("--quantize,!--no-quantize", io.quantize,
               "Quantise snapshots like state format 2")->capture_default_str();
  is->add_option("--position-step", io.position_step_m, "Quantisation step (m)")->capture_default_str();
  is->add_option("--rotation-bound", io.rotation_bound_deg, "Quantisation rotation bound (deg)")->capture_default_str();
  is->add_option("--json", interp_json, "Write results as JSON to this file");
  is->add_option("--charts", interp_charts, "Chart file prefix ('' for none)")->capture_default_str();

  // codec-sweep: format-2 bandwidth vs accuracy (offline).
  auto* cs = app.add_subcommand("codec-sweep", "Quantized delta codec: bandwidth vs accuracy (offline)");
  CodecSweepOptions co;
  std::string codec_steps = "0.0005,0.001,0.002,0.005", codec_bounds = "0.05,0.1,0.2,0.5";
  std::string codec_thresholds = "0,0.0005,0.001,0.005";
  std::string codec_json, codec_charts = "codec_sweep";
  cs->add_option("--steps", codec_steps, "Position steps (m) to sweep")->capture_default_str();
  cs->add_option("--rotation-bounds", codec_bounds, "Rotation bounds (deg) to sweep")->capture_default_str();
  cs->add_option("--thresholds", codec_thresholds,
                 "Selective-sync position thresholds (m) to sweep")->capture_default_str();
  cs->add_option("--position-step", co.default_position_step_m, "Default step (m)")->capture_default_str();
  cs->add_option("--rotation-bound", co.default_rotation_bound_deg, "Default rotation bound (deg)")->capture_default_str();
  cs->add_option("--threshold", co.default_threshold_m, "Default position threshold (m)")->capture_default_str();
  cs->add_option("--rotation-threshold-per-m", co.rotation_threshold_deg_per_m,
                 "Rotation threshold (deg) per metre of position threshold")->capture_default_str();
  cs->add_option("--objects", co.objects, "Objects")->capture_default_str();
  cs->add_option("--rate", co.rate_hz, "Sends per second per object")->capture_default_str();
  cs->add_option("--duration", co.duration_s, "Seconds per configuration")->capture_default_str();
  cs->add_option("--slow-fraction", co.slow_fraction,
                 "Fraction of objects that only creep (where thresholds matter)")->capture_default_str();
  cs->add_option("--slow-speed", co.slow_motion.speed_mps, "Creeping objects' speed (m/s)")->capture_default_str();
  cs->add_option("--slow-spin", co.slow_motion.spin_dps, "Creeping objects' spin (deg/s)")->capture_default_str();
  cs->add_option("--speed", co.motion.speed_mps, "Object speed (m/s)")->capture_default_str();
  cs->add_option("--spin", co.motion.spin_dps, "Object spin (deg/s)")->capture_default_str();
  cs->add_option("--seed", co.motion.seed, "Motion and loss seed")->capture_default_str();
  cs->add_option("--loss", co.loss, "Packet loss probability")->capture_default_str();
  cs->add_option("--json", codec_json, "Write results as JSON to this file");
  cs->add_option("--charts", codec_charts, "Chart file prefix ('' for none)")->capture_default_str();

  // multiobject: PhyS step time vs raw Bullet and PhyS egress (the paper's Obj_N).
  auto* mo = app.add_subcommand("multiobject", "PhyS MultiObject: step time vs raw Bullet, egress vs the paper");
  MultiObjectOptions moo;
  std::string mo_objects = "500,1000,2000,5000,10000";
  std::string mo_json, mo_charts = "multiobject";
  mo->add_option("--objects", mo_objects, "Box counts (comma separated)")->capture_default_str();
  mo->add_option("--duration", moo.duration_s, "Relay run: measured seconds per size")->capture_default_str();
  mo->add_option("--receivers", moo.receivers, "Relay run: receiving clients")->capture_default_str();
  mo->add_option("--settle-steps", moo.relay_settle_steps, "Relay run: PhyS steps before measuring")->capture_default_str();
  mo->add_option("--settle-max", moo.relay_settle_max_s, "Relay run: wall cap on settling (s)")->capture_default_str();
  mo->add_option("--relay-max-substeps", moo.relay_max_substeps,
                 "Relay run: PhysicsConfig::max_substeps (steps per relay update)")->capture_default_str();
  mo->add_option("--bench-warmup", moo.bench_warmup_steps, "Standalone: settling steps")->capture_default_str();
  mo->add_option("--bench-steps", moo.bench_steps, "Standalone: measured steps per scene (at most)")->capture_default_str();
  mo->add_option("--bench-max", moo.bench_max_s, "Standalone: wall cap on measuring (s)")->capture_default_str();
  mo->add_option("--bench-min-steps", moo.bench_min_steps, "Standalone: measured steps at least")->capture_default_str();
  mo->add_option("--moving-speed", moo.moving_speed_mps, "Moving: speed above (m/s)")->capture_default_str();
  mo->add_option("--seed", moo.seed, "Scene seed")->capture_default_str();
  mo->add_option("--stirrer-speed", moo.stirrer_angular_speed, "Stirrer angular speed (rad/s)")->capture_default_str();
  mo->add_option("--stirrer-reach", moo.stirrer_reach,
                 "Stirrer paddle half length / container half width (0.95: stirs everything)")
      ->capture_default_str();
  mo->add_option("--layers", moo.layers, "Container floor sized for this many layers of boxes")
      ->capture_default_str();
  mo->add_option("--stirrer-y", moo.stirrer_center_y, "Stirrer paddle centre height (m)")
      ->capture_default_str();
  mo->add_option("--stirrer-half-height", moo.stirrer_half_height,
                 "Stirrer paddle half height (m; 0.4 at y 0.4 spans the ~0.6 m pile)")
      ->capture_default_str();
  mo->add_option("--sleep-threshold", moo.sleep_threshold,
                 "PhyS sleeping thresholds (m/s, rad/s); Bullet's defaults are 0.8 / 1.0")
      ->capture_default_str();
  mo->add_option("--position-step", moo.position_step_m, "edgephys quantisation step (m)")->capture_default_str();
  mo->add_option("--rotation-bound", moo.rotation_bound_deg, "edgephys rotation bound (deg)")->capture_default_str();
  mo->add_option("--position-threshold", moo.position_threshold_m,
                 "Send when the client's copy is off by more than this (m; <0: relay default 0.001)")
      ->capture_default_str();
  mo->add_option("--rotation-threshold", moo.rotation_threshold_deg,
                 "Send when the client's copy is off by more than this (deg; <0: relay default 0.1)")
      ->capture_default_str();
  mo->add_option("--ambient-hz", moo.ambient_hz,
                 "Relay's send rate for boxes nobody touches (ReplicationConfig::ambient_hz; 0: default)")
      ->capture_default_str();
  mo->add_flag("!--no-bench", moo.bench, "Skip the standalone PhyS vs raw Bullet steps");
  mo->add_flag("!--no-relay", moo.relay, "Skip the relay run");
  mo->add_option("--json", mo_json, "Write results as JSON to this file");
  mo->add_option("--charts", mo_charts, "Chart file prefix ('' for none)")->capture_default_str();
  mo->add_flag("!--no-progress", moo.progress, "Hide the progress line");

  // softbody: bunnies poked by hands (the paper's Bunny_1 / Bunny_3).
  auto* sb = app.add_subcommand("softbody", "PhyS soft bodies: egress vs the paper, step time, error");
  SoftBodyOptions sbo;
  std::string sb_bunnies = "1,3";
  std::string sb_json, sb_charts = "softbody";
  sb->add_option("--bunnies", sb_bunnies, "Bunny counts (comma separated)")->capture_default_str();
  sb->add_option("--particles", sbo.particles, "Target particles per bunny")->capture_default_str();
  sb->add_option("--duration", sbo.duration_s, "Relay run: measured seconds per count")->capture_default_str();
  sb->add_option("--receivers", sbo.receivers, "Relay run: receiving clients")->capture_default_str();
  sb->add_option("--settle-steps", sbo.relay_settle_steps, "Relay run: PhyS steps before measuring")->capture_default_str();
  sb->add_option("--poke-period", sbo.poke_period_s, "Seconds per poke")->capture_default_str();
  sb->add_option("--bench-warmup", sbo.bench_warmup_steps, "Standalone: settling steps")->capture_default_str();
  sb->add_option("--bench-steps", sbo.bench_steps, "Standalone: measured steps")->capture_default_str();
  sb->add_option("--position-step", sbo.position_step_m, "edgephys quantisation step (m)")->capture_default_str();
  sb->add_option("--json", sb_json, "Write results as JSON to this file");
  sb->add_option("--charts", sb_charts, "Chart file prefix ('' for none)")->capture_default_str();
  sb->add_flag("!--no-progress", sbo.progress, "Hide the progress line");

  auto* ccu = app.add_subcommand("ccu", "Concurrent users: bots with hands and grabbed objects");
  CcuOptions ccu_o;
  std::string ccu_users = "100", ccu_json, ccu_charts = "ccu";
  ccu->add_option("--users", ccu_users, "User counts (comma separated; one run each)")->capture_default_str();
  ccu->add_option("--rooms", ccu_o.rooms, "Rooms the users spread over")->capture_default_str();
  ccu->add_option("--ramp", ccu_o.ramp_s, "Seconds over which users join")->capture_default_str();
  ccu->add_option("--duration", ccu_o.duration_s, "Measured seconds after the ramp")->capture_default_str();
  ccu->add_option("--tick-rate", ccu_o.tick_rate_hz, "Relay room tick rate")->capture_default_str();
  ccu->add_option("--relay-threads", ccu_o.relay_threads,
                  "Relay threads for ticks and PhyS (1: the relay keeps to one core; the bots use the other)")
      ->capture_default_str();
  ccu->add_option("--json", ccu_json, "Write results as JSON to this file");
  ccu->add_option("--charts", ccu_charts, "Chart file prefix ('' for none)")->capture_default_str();
  ccu->add_flag("!--no-progress", ccu_o.progress, "Hide the progress line");

  auto* ce = app.add_subcommand("ceiling",
                                "Relay packets/s and bytes/s vs the iperf3 -u loopback ceiling");
  CeilingOptions ce_o;
  std::string ce_threads = "1,2", ce_json;
  ce->add_option("--io-threads", ce_threads,
                 "Relay --io-threads values (comma separated; one run each)")
      ->capture_default_str();
  ce->add_option("--clients", ce_o.clients, "Bot clients")->capture_default_str();
  ce->add_option("--rooms", ce_o.rooms, "Rooms the clients spread over")->capture_default_str();
  ce->add_option("--entities", ce_o.entities_per_client, "Entities each client moves")
      ->capture_default_str();
  ce->add_option("--publish-hz", ce_o.publish_hz, "Client publish rate")->capture_default_str();
  ce->add_option("--tick-rate", ce_o.tick_rate_hz, "Relay room tick rate")->capture_default_str();
  ce->add_option("--warmup", ce_o.warmup_s, "Seconds of load before measuring")
      ->capture_default_str();
  ce->add_option("--duration", ce_o.duration_s, "Measured seconds per relay run")
      ->capture_default_str();
  ce->add_option("--iperf-seconds", ce_o.iperf_seconds, "iperf3 -t")->capture_default_str();
  ce->add_option("--iperf-length", ce_o.iperf_length,
                 "iperf3 -l (bytes; 0: the relay's mean datagram size)")
      ->capture_default_str();
  ce->add_option("--iperf-port", ce_o.iperf_port, "iperf3 port (0: a free one)")
      ->capture_default_str();
  ce->add_option("--repeat", ce_o.repeat, "Repetitions (medians reported)")->capture_default_str();
  ce->add_option("--json", ce_json, "Write results as JSON to this file");
  ce->add_flag("!--no-progress", ce_o.progress, "Hide progress lines");

  CLI11_PARSE(app, argc, argv);

  if (*ce) {
    if (!ParseList(ce_threads, &ce_o.io_threads) || ce_o.clients == 0 || ce_o.rooms == 0 ||
        ce_o.entities_per_client == 0 || ce_o.publish_hz <= 0 || ce_o.tick_rate_hz <= 0 ||
        ce_o.tick_rate_hz > 1000 || ce_o.warmup_s < 0 || ce_o.duration_s <= 0 ||
        ce_o.duration_s > 120 || ce_o.iperf_seconds <= 0 || ce_o.iperf_seconds > 120 ||
        ce_o.repeat == 0 || ce_o.repeat > 20) {
      std::cerr << "invalid ceiling options (durations 0..120 s, repeat 1..20, counts > 0)\n";
      return 2;
    }
    for (size_t t : ce_o.io_threads) {
      if (t == 0 || t > 64) {
        std::cerr << "--io-threads: values must be in 1..64\n";
        return 2;
      }
    }
    auto reps = RunCeiling(ce_o);
    auto summary = SummarizeCeiling(ce_o, reps);
    std::cout << CeilingTable(summary, reps);
    if (!ce_json.empty()) std::ofstream(ce_json) << CeilingJson(ce_o, reps, summary) << "\n";
    return 0;
  }

  if (*ccu) {
    if (!ParseList(ccu_users, &ccu_o.users) || ccu_o.rooms == 0 || ccu_o.duration_s <= 0) {
      std::cerr << "--users must be a list of counts; --rooms and --duration positive\n";
      return 2;
    }
    auto results = RunCcu(ccu_o);
    std::cout << CcuTable(results);
    if (!ccu_json.empty()) std::ofstream(ccu_json) << CcuJson(ccu_o, results) << "\n";
    if (!ccu_charts.empty()) WriteCcuCharts(results, ccu_charts);
    return 0;
  }

  if (*mo) {
    if (!ParseList(mo_objects, &moo.objects)) {
      std::cerr << "--objects: expected a comma-separated list of counts\n";
      return 2;
    }
    for (uint32_t n : moo.objects) {
      if (n == 0 || n > 60000) {
        std::cerr << "--objects: counts must be in 1..60000\n";
        return 2;
      }
    }
    if (moo.duration_s <= 0 || moo.receivers == 0 || moo.bench_steps <= 0 || moo.bench_warmup_steps < 0 ||
        moo.relay_settle_steps < 0 || moo.relay_max_substeps < 1) {
      std::cerr << "invalid --duration, --receivers, --bench-steps, --bench-warmup, --settle-steps "
                   "or --relay-max-substeps\n";
      return 2;
    }
    auto results = RunMultiObject(moo);
    std::cout << MultiObjectTable(results);
    if (!mo_json.empty()) std::ofstream(mo_json) << MultiObjectJson(moo, results) << "\n";
    if (!mo_charts.empty() && !WriteMultiObjectCharts(results, mo_charts)) {
      std::cerr << "could not write charts with prefix " << mo_charts << "\n";
      return 1;
    }
    for (const auto& r : results) {
      if (moo.relay && !r.relay_ok) return 1;
    }
    return 0;
  }

  if (*sb) {
    if (!ParseList(sb_bunnies, &sbo.bunnies)) {
      std::cerr << "--bunnies: expected a comma-separated list of counts\n";
      return 2;
    }
    for (uint32_t n : sbo.bunnies) {
      if (n == 0 || n > 64) {
        std::cerr << "--bunnies: counts must be in 1..64\n";
        return 2;
      }
    }
    if (sbo.duration_s <= 0 || sbo.receivers == 0 || sbo.particles < 10 || sbo.poke_period_s <= 0 ||
        sbo.bench_steps <= 0) {
      std::cerr << "invalid --duration, --receivers, --particles, --poke-period or --bench-steps\n";
      return 2;
    }
    auto results = RunSoftBody(sbo);
    std::cout << SoftBodyTable(results);
    if (!sb_json.empty()) std::ofstream(sb_json) << SoftBodyJson(sbo, results) << "\n";
    if (!sb_charts.empty() && !WriteSoftBodyCharts(results, sb_charts)) {
      std::cerr << "could not write charts with prefix " << sb_charts << "\n";
      return 1;
    }
    for (const auto& r : results) {
      if (!r.relay_ok) return 1;
    }
    return 0;
  }

  if (*is) {
    if (!ParseList(interp_rates, &io.rates_hz)) {
      std::cerr << "--rates: expected a comma-separated list of rates\n";
      return 2;
    }
    io.interpolators.clear();
    std::stringstream ss(interp_methods);
    std::string name;
    while (std::getline(ss, name, ',')) {
      Interpolator method;
      if (!ParseInterpolator(name, &method)) {
        std::cerr << "--interpolators: unknown interpolator '" << name << "'\n";
        return 2;
      }
      io.interpolators.push_back(method);
    }
    for (double r : io.rates_hz) {
      if (r <= 0) {
        std::cerr << "--rates must be positive\n";
        return 2;
      }
    }
    if (io.interpolators.empty() || io.duration_s <= 0 || io.warmup_s < 0 || io.objects == 0 ||
        io.render_hz <= 0 || impaired_latency_s < 0 || impaired_jitter_s < 0 ||
        impaired_loss < 0 || impaired_loss >= 1) {
      std::cerr << "invalid --interpolators, --duration, --warmup, --objects, --render-hz, "
                   "--latency, --jitter or --loss\n";
      return 2;
    }
    char impaired[64];
    std::snprintf(impaired, sizeof(impaired), "loss%g_jitter%g", impaired_loss * 100,
                  impaired_jitter_s * 1000);
    io.networks = {{"clean", impaired_latency_s, 0, 0},
                   {impaired, impaired_latency_s, impaired_jitter_s, impaired_loss}};
    auto results = RunInterpSweep(io);
    if (results.empty()) return 1;
    std::cout << InterpSweepTable(results);
    if (!interp_json.empty()) {
      std::ofstream(interp_json) << InterpSweepJson(io, results) << "\n";
    }
    if (!interp_charts.empty() && !WriteInterpSweepCharts(io, results, interp_charts)) {
      std::cerr << "could not write charts with prefix " << interp_charts << "\n";
      return 1;
    }
    return 0;
  }

  if (*cs) {
    if (!ParseList(codec_steps, &co.steps_m) || !ParseList(codec_bounds, &co.rotation_bounds_deg) ||
        !ParseList(codec_thresholds, &co.thresholds_m)) {
      std::cerr << "--steps, --rotation-bounds, --thresholds: expected comma-separated numbers\n";
      return 2;
    }
    if (co.objects == 0 || co.rate_hz <= 0 || co.duration_s <= 0 || co.loss < 0 || co.loss >= 1 ||
        co.slow_fraction < 0 || co.slow_fraction > 1) {
      std::cerr << "invalid --objects, --rate, --duration, --loss or --slow-fraction\n";
      return 2;
    }
    auto results = RunCodecSweep(co);
    if (results.empty()) return 1;
    std::cout << CodecSweepTable(results);
    if (!codec_json.empty()) {
      std::ofstream(codec_json) << CodecSweepJson(co, results) << "\n";
    }
    if (!codec_charts.empty() && !WriteCodecSweepCharts(co, results, codec_charts)) {
      std::cerr << "could not write charts with prefix " << codec_charts << "\n";
      return 1;
    }
    return 0;
  }

  if (*rc) {
    if (!ParseList(objects, &o.objects)) {
      std::cerr << "--objects: expected a comma-separated list of counts\n";
      return 2;
    }
    std::vector<std::string> names;
    std::stringstream ss(modes);
    std::string m;
    o.modes.clear();
    while (std::getline(ss, m, ',')) {
      ReplicationMode mode;
      if (!ParseReplicationMode(m, &mode)) {
        std::cerr << "--modes: unknown mode '" << m << "'\n";
        return 2;
      }
      o.modes.push_back(mode);
    }
    if (o.rate_hz <= 0 || o.duration_s <= 0 || o.receivers == 0) {
      std::cerr << "--rate, --duration and --receivers must be positive\n";
      return 2;
    }
    auto results = RunRelayCompare(o);
    std::cout << RelayCompareTable(results);
    if (!json_path.empty()) {
      std::ofstream(json_path) << RelayCompareJson(o, results) << "\n";
    }
    if (!chart_prefix.empty() && !WriteRelayCompareCharts(results, chart_prefix)) {
      std::cerr << "could not write charts with prefix " << chart_prefix << "\n";
      return 1;
    }
    return 0;
  }
  return 0;
}
