// The output module shared by every scenario: its common options (--json FILE, --charts PREFIX,
// --no-progress) and what a Report becomes (the table on stdout, the JSON file, <prefix>.dat and
// the charts drawn with loadgen/chart.h).
#pragma once

#include <string>

#include "loadgen/scenario.h"

namespace edgephys::loadgen {

struct OutputOptions {
  std::string json_path;     // "" for no JSON
  std::string chart_prefix;  // "" for no charts
};

// Adds the scenario's subcommand to `app`: its own options (their help shows their defaults),
// then --json, --charts (if the scenario draws charts; default its chart_prefix()) and
// --no-progress (if it has a progress switch), which fill `out` and the scenario's switch.
CLI::App* AddScenarioCommand(CLI::App& app, Scenario& scenario, OutputOptions* out);

// Validates and runs the scenario, then prints the table, writes the JSON and the charts.
// Returns the exit status: 2 invalid options, 1 the run or the charts failed, else 0.
int RunScenario(Scenario& scenario, const OutputOptions& out);

}  // namespace edgephys::loadgen
