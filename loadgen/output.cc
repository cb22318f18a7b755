#include "loadgen/output.h"

#include <CLI/CLI.hpp>
#include <cstdarg>
#include <cstdio>
#include <fstream>
#include <iostream>

namespace edgephys::loadgen {

void Table::Line(const char* format, ...) {
  char line[512];
  va_list args;
  va_start(args, format);
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(line, sizeof(line), format, args);
  va_end(args);
  if (n < 0) {
    va_end(again);
    return;
  }
  if (static_cast<size_t>(n) < sizeof(line)) {
    text_.append(line, static_cast<size_t>(n));
  } else {
    std::string long_line(static_cast<size_t>(n) + 1, '\0');
    std::vsnprintf(long_line.data(), long_line.size(), format, again);
    long_line.pop_back();
    text_ += long_line;
  }
  va_end(again);
}

void AddMotionOptions(CLI::App& cmd, MotionParams* motion, const char* seed_help) {
  cmd.add_option("--speed", motion->speed_mps, "Object speed (m/s)");
  cmd.add_option("--spin", motion->spin_dps, "Object spin (deg/s)");
  cmd.add_option("--seed", motion->seed, seed_help);
}

void AddWindowOptions(CLI::App& cmd, double* warmup_s, double* duration_s, const std::string& per) {
  cmd.add_option("--warmup", *warmup_s, "Seconds run before measuring");
  cmd.add_option("--duration", *duration_s, "Measured seconds" + per);
}

void AddQuantisationOptions(CLI::App& cmd, float* position_step_m, float* rotation_bound_deg) {
  cmd.add_option("--position-step", *position_step_m, "Position quantisation step (m)");
  cmd.add_option("--rotation-bound", *rotation_bound_deg, "Rotation quantisation bound (deg)");
}

void AddRelayRoomOptions(CLI::App& cmd, double* tick_rate_hz, bool* packet_auth) {
  cmd.add_option("--tick-rate", *tick_rate_hz, "Relay room tick rate");
  cmd.add_option("--packet-auth", *packet_auth,
                 "In-process relay: seal packets after the handshake (false: measure without)");
}

void AddSceneRelayRunOptions(CLI::App& cmd, double* duration_s, uint32_t* receivers,
                             int* settle_steps, const char* size) {
  cmd.add_option("--duration", *duration_s, std::string("Relay run: measured seconds per ") + size);
  cmd.add_option("--receivers", *receivers, "Relay run: receiving clients");
  cmd.add_option("--settle-steps", *settle_steps, "Relay run: PhyS steps before measuring");
}

void AddStandaloneStepOptions(CLI::App& cmd, int* warmup_steps, int* steps) {
  cmd.add_option("--bench-warmup", *warmup_steps, "Standalone: settling steps");
  cmd.add_option("--bench-steps", *steps, "Standalone: measured steps per scene (at most)");
}

std::vector<std::unique_ptr<Scenario>> AllScenarios() {
  std::vector<std::unique_ptr<Scenario>> all;
  all.push_back(MakeRelayCompareScenario());
  all.push_back(MakeInterpSweepScenario());
  all.push_back(MakeCodecSweepScenario());
  all.push_back(MakeMultiObjectScenario());
  all.push_back(MakeSoftBodyScenario());
  all.push_back(MakeCcuScenario());
  all.push_back(MakeCeilingScenario());
  all.push_back(MakeIsolationScenario());
  all.push_back(MakePhysicsBurnScenario());
  all.push_back(MakeHostileScenario());
  all.push_back(MakeMessagesScenario());
  return all;
}

CLI::App* AddScenarioCommand(CLI::App& app, Scenario& scenario, OutputOptions* out) {
  CLI::App* cmd = app.add_subcommand(scenario.name(), scenario.description());
  cmd->option_defaults()->always_capture_default();
  scenario.AddOptions(*cmd);
  cmd->option_defaults()->always_capture_default(false);
  cmd->add_option("--json", out->json_path, "Write results as JSON to this file");
  out->chart_prefix = scenario.chart_prefix();
  if (!out->chart_prefix.empty()) {
    cmd->add_option("--charts", out->chart_prefix, "Chart file prefix ('' for none)")
        ->capture_default_str();
  }
  if (bool* progress = scenario.progress()) {
    cmd->add_flag("!--no-progress", *progress, scenario.progress_help());
  }
  return cmd;
}

namespace {

// <prefix>.dat and every chart's scripts; the images if gnuplot is on PATH.
bool WriteCharts(const ChartSet& set, const std::string& prefix) {
  {
    std::ofstream dat(prefix + ".dat");
    if (!dat) return false;
    dat << set.data;
    dat.close();
    if (!dat) return false;
  }
  for (const chart::Chart& c : set.charts) {
    if (!chart::Write(c)) return false;
    (void)chart::Render(c);  // images are best effort, like gnuplot itself being optional
  }
  return true;
}

}  // namespace

int RunScenario(Scenario& scenario, const OutputOptions& out) {
  if (const std::string error = scenario.Validate(); !error.empty()) {
    std::cerr << error << "\n";
    return 2;
  }
  std::optional<Report> report = scenario.Run();
  if (!report) return 1;
  std::cout << report->table.str();
  if (!out.json_path.empty()) std::ofstream(out.json_path) << report->json.dump(2) << "\n";
  if (report->charts && !out.chart_prefix.empty() &&
      !WriteCharts(report->charts(out.chart_prefix), out.chart_prefix)) {
    std::cerr << "could not write charts with prefix " << out.chart_prefix << "\n";
    return 1;
  }
  return report->ok ? 0 : 1;
}

}  // namespace edgephys::loadgen
