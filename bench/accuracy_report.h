// Shared pieces of physics_accuracy_report (bench/physics_accuracy_report.cc): output files and
// charts in --out, timing helpers, and the experiments, one function each, that main() runs.
#pragma once

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>
#include <vector>

#include "loadgen/chart.h"
#include "physics_backend/physics_world.h"
#include "physics_backend/testing/physics_probes.h"

namespace edgephys::physics {

inline constexpr double kG = 9.81;
inline constexpr double kPi = 3.14159265358979323846;

// The --out directory every OutFile and chart goes to.
extern std::string g_out;

// Adds `spec` to `world`; exits with status 2 naming the reason when PhyS refuses it.
bool AddSpec(PhysicsWorld& world, const EntitySpec& spec);

using testing::Pos;
using testing::Vel;

inline double Distance(const Vec3f& a, const Vec3f& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}

// A file in --out that is written line by line.
class OutFile {
 public:
  explicit OutFile(const std::string& name) : path_(g_out + "/" + name), f_(path_) {
    if (!f_) {
      std::fprintf(stderr, "cannot write %s\n", path_.c_str());
      std::exit(2);
    }
  }
  template <typename... Args>
  void Printf(const char* fmt, Args... args) {
    char buf[1024];
    std::snprintf(buf, sizeof buf, fmt, args...);
    f_ << buf;
  }
  void Write(const std::string& s) { f_ << s; }

 private:
  std::string path_;
  std::ofstream f_;
};

// The chart <stem>.gp in --out: run there, it renders the same plot commands (the body,
// indented for the script's loop) to <stem>.png and <stem>.svg.
chart::Chart ReportChart(const std::string& stem, int width = 0, int height = 0,
                         const std::string& body = "");
// Writes ReportChart(stem, ...); exits with status 2 when it cannot.
void WriteGnuplot(const std::string& stem, int width, int height, const std::string& body);
// CPU time of the calling thread (ms): less sensitive than wall time to other processes
// sharing the cores.
double ThreadCpuMs();
double Median(std::vector<double> v);

// The bounce experiment (testing::BounceApexes: apex heights of a sphere dropped from h0 with
// restitution e) with `substeps` and `iterations`, at most 30 s.
std::vector<double> BounceApexes(int substeps, float e, float h0, int max_apexes,
                                 double min_height, int iterations = 10);

// The ten-box stack: 0.5 m, 1 kg cubes in exact contact on a static ground (friction 0.5).
struct StackSetting {
  const char* name;
  int substeps;
  int iterations;
  bool sleeping;
  float sleep_lin;
  float sleep_ang;
};
struct StackRun {
  double max_drift = 0;      // any box, over the run
  double top_drift = 0;      // top box at the end
  size_t sleeping_end = 0;
};
StackRun Stack(const StackSetting& s, double seconds, OutFile* series, int sample_every);

// The experiments (accuracy_rigid.cc: the first five; physics_accuracy_report.cc: the rest).
void RunFreeFall();
void RunBounce();
void RunFriction();
void RunStack();
void RunCcd();
void RunSoft();
void RunSpeed(int warmup, int measured);

}  // namespace edgephys::physics
