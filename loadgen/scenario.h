// Scenario: one edgephys-loadgen subcommand. A scenario owns its options and its run; what it
// produces is a Report, which the one output module (loadgen/output.h) turns into the table on
// stdout, the --json file and the --charts files, the same way for every scenario.
#pragma once

#include <algorithm>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "loadgen/chart.h"
#include "loadgen/motion.h"

namespace CLI {
class App;
}  // namespace CLI

namespace edgephys::loadgen {

// The console table of a report, built line by line.
class Table {
 public:
  // Appends printf(format, ...); the format carries its own "\n".
  void Line(const char* format, ...) __attribute__((format(printf, 2, 3)));
  void Text(std::string_view text) { text_ += text; }
  const std::string& str() const { return text_; }

 private:
  std::string text_;
};

// What --charts PREFIX writes: <prefix>.dat, then every chart (stems begin with the prefix).
struct ChartSet {
  std::string data;
  std::vector<chart::Chart> charts;
};

struct Report {
  nlohmann::json json;  // --json FILE: json.dump(2) and a newline
  Table table;          // printed on stdout
  // The charts for a --charts prefix; unset: the scenario draws none.
  std::function<ChartSet(const std::string& prefix)> charts;
  // False: the run itself failed (e.g. a relay run could not measure). The outputs are still
  // written; the exit status is 1.
  bool ok = true;
};

class Scenario {
 public:
  // `chart_prefix`: the default --charts prefix; "" if the scenario draws no charts (then it has
  // no --charts option).
  Scenario(const char* name, const char* description, const char* chart_prefix = "")
      : name_(name), description_(description), chart_prefix_(chart_prefix) {}
  virtual ~Scenario() = default;
  Scenario(const Scenario&) = delete;
  Scenario& operator=(const Scenario&) = delete;

  const char* name() const { return name_; }                // the subcommand
  const char* description() const { return description_; }  // its help line
  const char* chart_prefix() const { return chart_prefix_; }
  // The switch --no-progress turns off (nullptr: the scenario has no such flag), and its help.
  bool* progress() const { return progress_; }
  const char* progress_help() const { return progress_help_; }

  // Adds the scenario's own options to its subcommand.
  virtual void AddOptions(CLI::App& cmd) = 0;
  // After parsing: converts list options and checks them. An error message (exit status 2)
  // or "".
  virtual std::string Validate() = 0;
  // Runs the scenario; nullopt: nothing to report (exit status 1, no outputs).
  virtual std::optional<Report> Run() = 0;

 protected:
  void SetProgressFlag(bool* on, const char* help = "Hide the progress line") {
    progress_ = on;
    progress_help_ = help;
  }

 private:
  const char* name_;
  const char* description_;
  const char* chart_prefix_;
  bool* progress_ = nullptr;
  const char* progress_help_ = "";
};

// The formatters of a scenario's report, each given the options and the results:
// json(o, results), table(o, results, &table) and, unless null, charts(o, results, prefix).
// json gives an object; MeasuringScenario adds its "scenario" (the subcommand's name).
template <typename Options, typename Results>
struct ReportFormat {
  nlohmann::json (*json)(const Options&, const Results&);
  void (*table)(const Options&, const Results&, Table*);
  ChartSet (*charts)(const Options&, const Results&, const std::string&) = nullptr;
};

// A scenario that measures Results from the Options its flags fill (o_) and reports them
// through its ReportFormat. Options with a `bool progress` member get the --no-progress switch
// (the default help; a scenario may call SetProgressFlag again for its own).
template <typename Options, typename Results>
class MeasuringScenario : public Scenario {
 public:
  MeasuringScenario(const char* name, const char* description,
                    ReportFormat<Options, Results> format, const char* chart_prefix = "")
      : Scenario(name, description, chart_prefix), format_(format) {
    if constexpr (requires(Options& o) { o.progress = true; }) SetProgressFlag(&o_.progress);
  }

  std::optional<Report> Run() final {
    std::optional<Results> results = Measure();
    if (!results) return std::nullopt;
    Report report;
    report.ok = Succeeded(*results);
    report.json = format_.json(o_, *results);
    report.json["scenario"] = name();
    format_.table(o_, *results, &report.table);
    if (format_.charts != nullptr) {
      report.charts = [o = o_, r = std::move(*results), charts = format_.charts](
                          const std::string& prefix) { return charts(o, r, prefix); };
    }
    return report;
  }

 protected:
  // The run, after Validate(); nullopt: nothing to report (exit status 1, no outputs).
  virtual std::optional<Results> Measure() = 0;
  // False: the run itself failed (Report::ok).
  virtual bool Succeeded(const Results&) const { return true; }

  Options o_;

 private:
  ReportFormat<Options, Results> format_;
};

// The results of a run, or nullopt (nothing to report) where there are none.
template <typename Result>
std::optional<std::vector<Result>> NonEmpty(std::vector<Result> results) {
  if (results.empty()) return std::nullopt;
  return results;
}

// True if the relay run behind every result succeeded (each Result's `relay_ok`).
template <typename Result>
bool AllRelayRunsOk(const std::vector<Result>& results) {
  return std::all_of(results.begin(), results.end(), [](const Result& r) { return r.relay_ok; });
}

// a / b, or 0 where b is not positive (a ratio to a Decoupled Edge Physics figure it lacks).
inline double RatioOr0(double a, double b) { return b > 0 ? a / b : 0.0; }

// The JSON of a Motion's parameters: speed_mps, spin_dps and seed.
NLOHMANN_DEFINE_TYPE_NON_INTRUSIVE(MotionParams, speed_mps, spin_dps, seed)

// Option groups several scenarios share: each declares its options' names and help once.

// --speed, --spin and --seed of the objects' Motion (loadgen/motion.h).
void AddMotionOptions(CLI::App& cmd, MotionParams* motion, const char* seed_help);

// --warmup (seconds run before measuring) and --duration (measured seconds; `per` says what
// one measured window covers, e.g. " per mode and size").
void AddWindowOptions(CLI::App& cmd, double* warmup_s, double* duration_s, const std::string& per);

// --position-step (m) and --rotation-bound (deg): the quantisation of positions and rotations.
void AddQuantisationOptions(CLI::App& cmd, float* position_step_m, float* rotation_bound_deg);

// --tick-rate (the relay's room tick rate) and --packet-auth (the in-process relay seals
// packets after the handshake; false: measure without).
void AddRelayRoomOptions(CLI::App& cmd, double* tick_rate_hz, bool* packet_auth);

// The relay run of a PhyS scene (multiobject, softbody): --duration (measured seconds per
// `size`, e.g. "size"), --receivers (receiving clients) and --settle-steps (PhyS steps before
// measuring).
void AddSceneRelayRunOptions(CLI::App& cmd, double* duration_s, uint32_t* receivers,
                             int* settle_steps, const char* size);

// The standalone step-time run of a PhyS scene: --bench-warmup (settling steps) and
// --bench-steps (measured steps, at most).
void AddStandaloneStepOptions(CLI::App& cmd, int* warmup_steps, int* steps);

// Every scenario, in the order of `edgephys-loadgen --help`.
std::vector<std::unique_ptr<Scenario>> AllScenarios();

std::unique_ptr<Scenario> MakeRelayCompareScenario();
std::unique_ptr<Scenario> MakeInterpSweepScenario();
std::unique_ptr<Scenario> MakeCodecSweepScenario();
std::unique_ptr<Scenario> MakeMultiObjectScenario();
std::unique_ptr<Scenario> MakeSoftBodyScenario();
std::unique_ptr<Scenario> MakeCcuScenario();
std::unique_ptr<Scenario> MakeCeilingScenario();
std::unique_ptr<Scenario> MakeIsolationScenario();
std::unique_ptr<Scenario> MakePhysicsBurnScenario();  // isolation's control (isolation.h)
std::unique_ptr<Scenario> MakeHostileScenario();
std::unique_ptr<Scenario> MakeMessagesScenario();

// "1,2,3" -> {1, 2, 3}. False if an item does not parse as T or the list is empty.
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

// "a,b" -> {parse("a"), parse("b")} with `bool parse(const std::string&, T*)`. False at the
// first unknown name, which goes to *unknown. An empty text gives an empty list.
template <typename T, typename Parse>
bool ParseNames(const std::string& text, Parse parse, std::vector<T>* out, std::string* unknown) {
  out->clear();
  std::stringstream ss(text);
  std::string name;
  while (std::getline(ss, name, ',')) {
    T v;
    if (!parse(name, &v)) {
      *unknown = name;
      return false;
    }
    out->push_back(v);
  }
  return true;
}

}  // namespace edgephys::loadgen
