// edgephys-loadgen: bot users and the paper's scenarios against edgephys and its emulated
// baselines. Every scenario (loadgen/scenario.h) is a subcommand; each prints a table and takes
// --json FILE, and those that draw charts --charts PREFIX (loadgen/output.h).
//
//   edgephys-loadgen relay-compare --objects 32,64,128,256,512 --modes photon,paper,edgephys
//   edgephys-loadgen interp-sweep --rates 6,12,24,30,48,60 --interpolators lerp-slerp,hermite
//   edgephys-loadgen codec-sweep --steps 0.0005,0.001,0.002,0.005 --thresholds 0,0.0005
//   edgephys-loadgen multiobject --objects 500,1000,2000,5000,10000
//   edgephys-loadgen softbody --bunnies 1,3
//   edgephys-loadgen ceiling --io-threads 1,2 --repeat 3 --json ceiling.json
//   edgephys-loadgen isolation --users 50 --boxes 10000 --phase 10
//   edgephys-loadgen hostile --attacks physics,names,churn,flood,forged,invalid --phase 4
//   edgephys-loadgen messages --users 25 --rate 40 --seconds 10
//   edgephys-loadgen ccu --users 100 --relay 127.0.0.1:7777 --secret S --relay-pid PID
#include <CLI/CLI.hpp>
#include <spdlog/spdlog.h>

#include "loadgen/output.h"
#include "loadgen/scenario.h"

int main(int argc, char** argv) {
  using namespace edgephys::loadgen;
  CLI::App app{"edgephys-loadgen: load generator and benchmark scenarios"};
  app.require_subcommand(1);
  spdlog::set_level(spdlog::level::warn);

  const std::vector<std::unique_ptr<Scenario>> scenarios = AllScenarios();
  std::vector<CLI::App*> commands;
  std::vector<OutputOptions> outputs(scenarios.size());
  for (size_t i = 0; i < scenarios.size(); ++i) {
    commands.push_back(AddScenarioCommand(app, *scenarios[i], &outputs[i]));
  }
  CLI11_PARSE(app, argc, argv);

  for (size_t i = 0; i < scenarios.size(); ++i) {
    if (*commands[i]) return RunScenario(*scenarios[i], outputs[i]);
  }
  return 0;
}
