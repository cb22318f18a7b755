#include "loadgen/isolation.h"

#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <thread>
#include <vector>

#include "loadgen/scenario.h"
#include "loadgen/scenes/scenes.h"

extern char** environ;

namespace edgephys::loadgen {
namespace {

std::atomic<bool> g_burn_stop{false};
void OnBurnSignal(int) { g_burn_stop.store(true); }

}  // namespace

PhysicsBurnResult RunPhysicsBurn(const PhysicsBurnOptions& o) {
  PhysicsBurnResult r;
  if (o.nice > 0) {
    errno = 0;
    (void)setpriority(PRIO_PROCESS, 0, getpriority(PRIO_PROCESS, 0) + o.nice);
  }
  r.niceness = getpriority(PRIO_PROCESS, 0);
  std::signal(SIGTERM, OnBurnSignal);
  std::signal(SIGINT, OnBurnSignal);
  physics::MultiObjectParams p;
  p.num_objects = static_cast<int>(o.boxes);
  p.seed = o.seed;
  // As the relay runs room B (loadgen/isolation.cc InProcessConfig).
  p.config.max_substeps = 1;
  p.config.sleep_linear_threshold = 0.1f;
  p.config.sleep_angular_threshold = 0.1f;
  physics::PhysSMultiObjectScene scene(p);
  using Clock = std::chrono::steady_clock;
  const Clock::time_point start = Clock::now();
  double stepping = 0;
  while (!g_burn_stop.load()) {
    const Clock::time_point t = Clock::now();
    if (std::chrono::duration<double>(t - start).count() >= o.seconds) break;
    scene.Step();
    stepping += std::chrono::duration<double>(Clock::now() - t).count();
    ++r.steps;
  }
  r.seconds = std::chrono::duration<double>(Clock::now() - start).count();
  r.step_ms_mean = r.steps > 0 ? stepping / r.steps * 1000 : 0;
  return r;
}

PhysicsBurnProcess::~PhysicsBurnProcess() { (void)Stop(); }

bool PhysicsBurnProcess::Start(const PhysicsBurnOptions& o, std::string* error) {
  if (pid_ > 0) {
    *error = "physics-burn already running";
    return false;
  }
  json_path_ = "/tmp/edgephys-physics-burn-" + std::to_string(getpid()) + ".json";
  std::vector<std::string> args = {"edgephys-loadgen", "physics-burn", "--boxes", std::to_string(o.boxes),
                                   "--seconds", std::to_string(o.seconds), "--nice", std::to_string(o.nice),
                                   "--seed", std::to_string(o.seed), "--json", json_path_};
  std::vector<char*> argv;
  for (std::string& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  const int rc = posix_spawn(&pid_, "/proc/self/exe", &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    pid_ = -1;
    *error = std::string("cannot start physics-burn: ") + std::strerror(rc);
    return false;
  }
  return true;
}

bool PhysicsBurnProcess::Stop(PhysicsBurnResult* result, std::string* error) {
  if (pid_ <= 0) {
    if (error != nullptr) *error = "physics-burn not running";
    return false;
  }
  (void)kill(pid_, SIGTERM);
  int status = 0;
  bool exited = false;
  for (int i = 0; i < 1000 && !exited; ++i) {
    exited = waitpid(pid_, &status, WNOHANG) == pid_;
    if (!exited) std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  if (!exited) {
    (void)kill(pid_, SIGKILL);
    (void)waitpid(pid_, &status, 0);
  }
  pid_ = -1;
  bool ok = exited && WIFEXITED(status) && WEXITSTATUS(status) == 0;
  nlohmann::json j;
  {
    std::ifstream in(json_path_);
    j = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  }
  (void)std::remove(json_path_.c_str());
  if (!j.is_object() || !j.contains("summary") || !j["summary"].is_object()) {
    ok = false;
  } else if (result != nullptr) {
    const nlohmann::json& s = j["summary"];
    result->steps = s.value("steps", uint64_t{0});
    result->seconds = s.value("seconds", 0.0);
    result->step_ms_mean = s.value("step_ms_mean", 0.0);
    result->niceness = s.value("niceness", 0);
  }
  if (!ok && error != nullptr) *error = "physics-burn did not finish cleanly";
  return ok;
}

namespace {

nlohmann::json Json(const PhysicsBurnOptions& o, const PhysicsBurnResult& r) {
  return {
      {"options", {{"boxes", o.boxes}, {"seconds", o.seconds}, {"nice", o.nice}, {"seed", o.seed}}},
      {"summary",
       {{"steps", r.steps},
        {"seconds", r.seconds},
        {"step_ms_mean", r.step_ms_mean},
        {"niceness", r.niceness}}}};
}

void FillTable(const PhysicsBurnOptions& o, const PhysicsBurnResult& r, Table* t) {
  t->Line("physics-burn: %u boxes, %llu steps in %.1f s, mean step %.2f ms, niceness %d\n", o.boxes,
          static_cast<unsigned long long>(r.steps), r.seconds, r.step_ms_mean, r.niceness);
}

class PhysicsBurnScenario final : public MeasuringScenario<PhysicsBurnOptions, PhysicsBurnResult> {
 public:
  PhysicsBurnScenario()
      : MeasuringScenario("physics-burn",
                          "Control for isolation: step the multiobject scene back to back in this "
                          "process, no relay",
                          {Json, FillTable}) {}

  void AddOptions(CLI::App& cmd) override {
    cmd.add_option("--boxes", o_.boxes, "Boxes in the scene");
    cmd.add_option("--seconds", o_.seconds, "Stop after this long (or at SIGTERM / SIGINT)");
    cmd.add_option("--nice", o_.nice, "Niceness added to this process first")->check(CLI::Range(0, 19));
    cmd.add_option("--seed", o_.seed, "Scene seed");
  }
  std::string Validate() override {
    if (o_.boxes == 0 || !(o_.seconds > 0)) return "--boxes and --seconds must be positive";
    return "";
  }
  std::optional<PhysicsBurnResult> Measure() override { return RunPhysicsBurn(o_); }
};

}  // namespace

std::unique_ptr<Scenario> MakePhysicsBurnScenario() { return std::make_unique<PhysicsBurnScenario>(); }

}  // namespace edgephys::loadgen
