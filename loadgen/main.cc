// edgephys-loadgen: bot users and the paper's scenarios against edgephys and its emulated
// baselines. Every scenario writes --json FILE, prints a table and writes gnuplot charts.
//
//   edgephys-loadgen relay-compare --objects 32,64,128,256,512 --modes photon,paper,edgephys
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include <fstream>
#include <iostream>
#include <sstream>

#include "loadgen/relay_compare.h"
#include "loadgen/report.h"

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

  CLI11_PARSE(app, argc, argv);

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
