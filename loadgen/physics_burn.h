// physics-burn: a control for `isolation`. Steps the multiobject scene (physics/scenes.h, the
// scene room B offloads to the relay's PhyS) back to back, as fast as one thread can, in a
// process of its own that is not the relay: the CPU and memory load of B's physics thread
// without any relay work. `isolation --b-mode burn` starts it for its with_b phase.
//
// Runs until `seconds` have passed or SIGTERM / SIGINT arrives (checked between steps, so it
// ends within one step: ~60 ms at 10,000 boxes). `nice`: added to this process's niceness
// first (0..19), as --physics-nice does for the relay's physics threads.
#pragma once

#include <sys/types.h>

#include <cstdint>
#include <string>

namespace edgephys::loadgen {

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
