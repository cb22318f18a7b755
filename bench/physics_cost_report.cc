// physics_cost_report: "model no more than the scene needs", measured. For every candidate
// setting of PhysicsConfig it reports, in one run:
//   * step time: PhysSMultiObjectScene (PhyS with the candidate) against
//     RawBulletMultiObjectScene (Bullet with its default settings) on the same scene, stepped
//     interleaved (the one stepped first alternating), medians of the timed steps and their
//     ratio;
//   * accuracy: the accuracy suite's experiments (physics/physics_accuracy_test.cc) run with the
//     candidate as the base config, with the suite's own pass bounds: free fall, restitution,
//     friction, ten-box stack (60 s), CCD; plus the scene's own figures (deepest contact
//     penetration, boxes outside the container, moving share).
// Prints one CSV row per candidate, writes physics_cost.dat and a gnuplot chart
// (physics_cost.png/.svg: step-time ratio against stack drift, failing candidates marked).
//
//   physics_cost_report [--objects 2000] [--layers 3] [--stirrer-reach 0.95]
//       [--stirrer-speed 1.5] [--warmup 120] [--steps 240] [--only name,name] [--out DIR]
//       [--render] [--label TEXT] [--realtime 1000,1500,2000,...] [--suite-substep S]
//
// --realtime: instead of candidates, steps the default-config scene at each size and prints the
// median step time and real-time factor (1/60 s over the median), to find the largest box count
// stepped in real time.
#include <BulletSoftBody/btSoftBody.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "loadgen/chart.h"
#include "bench/physics_cost_candidates.h"
#include "physics_backend/container_builder.h"
#include "physics_backend/physics_world.h"
#include "physics_backend/testing/physics_probes.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {
namespace {

constexpr double kG = 9.81;

// ---------------------------------------------------------------------------------------------
// Accuracy: the suite's experiments with `base` as the config.

using testing::Ground;
using testing::Pos;
using testing::Vel;

void FailedToAdd(uint32_t id) {
  std::fprintf(stderr, "AddEntity(%u) failed\n", id);
  std::exit(2);
}
void Add(PhysicsWorld& w, const EntitySpec& spec) {
  if (!testing::Add(w, spec).ok()) FailedToAdd(spec.id);
}
double Dist(const Vec3f& a, const Vec3f& b) {
  return std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) + (a.z - b.z) * (a.z - b.z));
}

struct Accuracy {
  double freefall_err = 0;      // max |y - symplectic prediction| (m), bound 1e-4
  double bounce_worst = 0;      // worst apex ratio / e^2 outside [1, 1.35] -> fail; reported as max |ratio/e^2 - 1|
  bool bounce_ok = true;
  double friction_worst = 0;    // worst |a - predicted| / predicted at 35 and 45 deg
  bool friction_ok = true;
  double stack_drift = 0;       // 60 s, 4 substeps, sleep 0.8/1.0 (the test's settings)
  double stack_awake = 0;       // 60 s, 4 substeps, never sleeping (bound 0.25 m)
  double ccd_max_x = 0;         // sphere centre, bound 0.955
  bool ok() const {
    return freefall_err < 1e-4 && bounce_ok && friction_ok && stack_drift < 0.01 &&
           stack_awake < 0.25 && ccd_max_x + 0.05 <= 1.005;
  }
};

double FreeFallErr(const PhysicsConfig& base) {
  PhysicsConfig cfg = base;
  PhysicsWorld w(cfg);
  Add(w, DynamicSphere(1, {0, 0, 0}, 0.1f, 1.0f));
  const double dt = cfg.fixed_dt;
  double err = 0;
  for (int n = 1; n <= 120; ++n) {
    w.Step();
    err = std::max(err, std::abs(Pos(w, 1).y + kG * dt * dt * n * (n + 1) / 2.0));
  }
  return err;
}

// Apex ratios h(n)/h(n-1) for a sphere dropped from 2 m (4 substeps, as the test).
// --suite-substep S (seconds, 0: off): the bounce and stack experiments take fixed_dt / S
// substeps instead of the suite's 4, i.e. they keep the suite's substep length (1/240 s at
// 60 Hz) at other rates. Diagnostic only: the suite itself (ctest) uses 4.
double g_suite_substep_s = 0;
int SuiteSubsteps(const PhysicsConfig& c) {
  if (g_suite_substep_s <= 0) return 4;
  return std::max(1, static_cast<int>(std::lround(c.fixed_dt / g_suite_substep_s)));
}

std::vector<double> BounceRatios(const PhysicsConfig& base, float e, bool ccd) {
  PhysicsConfig cfg = base;
  cfg.substeps = SuiteSubsteps(base);
  cfg.ccd = ccd;
  const testing::BounceRun run = testing::BounceApexes(cfg, e, 2.0f, 4, 0.1, 1200);
  if (!run.added.ok()) {
    std::fprintf(stderr, "bounce scene: AddEntity failed\n");
    std::exit(2);
  }
  const std::vector<double>& h = run.heights;
  std::vector<double> ratios;
  for (size_t i = 1; i < h.size(); ++i) ratios.push_back(h[i] / h[i - 1]);
  return ratios;
}

// Cube on flat ground under gravity tilted by `angle`: (displacement after `seconds`,
// acceleration from the velocities at 0.5 s and 1.5 s).
std::pair<double, double> Slope(const PhysicsConfig& base, double angle, double seconds) {
  PhysicsConfig cfg = base;
  cfg.gravity = Vec3f{static_cast<float>(kG * std::sin(angle)),
                      static_cast<float>(-kG * std::cos(angle)), 0};
  PhysicsWorld w(cfg);
  Add(w, Ground(1, 1.0f));
  EntitySpec cube = DynamicBox(2, {0, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  cube.rigid_body->friction = 0.5f;
  Add(w, cube);
  double v1 = 0, a = 0;
  const double dt = cfg.fixed_dt;
  const int at_half = static_cast<int>(0.5 / dt + 0.5), at_1_5 = static_cast<int>(1.5 / dt + 0.5);
  for (int i = 1; i <= static_cast<int>(seconds / dt + 0.5); ++i) {
    w.Step();
    if (i == at_half) v1 = Vel(w, 2).x;
    if (i == at_1_5) a = Vel(w, 2).x - v1;
  }
  return {Pos(w, 2).x, a};
}

double StackDrift(const PhysicsConfig& cfg, double seconds) {
  PhysicsWorld w(cfg);
  const testing::BoxStack stack = testing::MakeBoxStack();
  for (const EntitySpec& spec : stack.specs) Add(w, spec);
  const std::vector<Vec3f>& start = stack.start;
  double drift = 0;
  for (int s = 0; s < static_cast<int>(seconds / cfg.fixed_dt + 0.5); ++s) {
    w.Step();
    for (uint32_t i = 0; i < 10; ++i) drift = std::max(drift, Dist(Pos(w, 10 + i), start[i]));
  }
  return drift;
}

double CcdMaxX(const PhysicsConfig& base) {
  PhysicsConfig cfg = base;
  cfg.ccd = true;
  PhysicsWorld w(cfg);
  Add(w, StaticBox(1, {1.0f, 0, 0}, {0.005f, 1.0f, 1.0f}));
  EntitySpec ball = DynamicSphere(2, {0, 0, 0}, 0.05f, 0.1f);
  ball.rigid_body->use_gravity = false;
  ball.rigid_body->linear_velocity = Vec3f{50.0f, 0, 0};
  Add(w, ball);
  double mx = 0;
  for (int i = 0; i < 30; ++i) {
    w.Step();
    mx = std::max<double>(mx, Pos(w, 2).x);
  }
  return mx;
}

Accuracy MeasureAccuracy(const PhysicsConfig& base) {
  Accuracy a;
  a.freefall_err = FreeFallErr(base);
  for (const float e : {0.5f, 0.8f}) {
    for (const bool ccd : {true, false}) {
      const std::vector<double> r = BounceRatios(base, e, ccd);
      if (r.size() < (e < 0.6f ? 2u : 3u)) a.bounce_ok = false;
      for (double x : r) {
        const double q = x / (e * e);
        a.bounce_worst = std::max(a.bounce_worst, std::abs(q - 1));
        if (q <= 1.0 || q >= 1.35) a.bounce_ok = false;
      }
    }
  }
  const double mu = 0.5, crit = std::atan(mu), margin = 3.0 * M_PI / 180.0;
  const auto stick = Slope(base, crit - margin, 2.0);
  const auto slide = Slope(base, crit + margin, 2.0);
  const double a_slide = kG * (std::sin(crit + margin) - mu * std::cos(crit + margin));
  if (std::abs(stick.first) >= 2e-3 || slide.first <= a_slide) a.friction_ok = false;
  for (const double deg : {35.0, 45.0}) {
    const double th = deg * M_PI / 180.0;
    const double expect = kG * (std::sin(th) - mu * std::cos(th));
    const double got = Slope(base, th, 1.6).second;
    a.friction_worst = std::max(a.friction_worst, std::abs(got - expect) / expect);
    if (std::abs(got - expect) > 0.03 * expect + 0.02) a.friction_ok = false;
  }
  PhysicsConfig stack = base;
  stack.substeps = SuiteSubsteps(base);
  stack.sleep_linear_threshold = 0.8f;
  stack.sleep_angular_threshold = 1.0f;
  a.stack_drift = StackDrift(stack, 60.0);
  PhysicsConfig awake = base;
  awake.substeps = SuiteSubsteps(base);
  awake.sleeping = false;
  a.stack_awake = StackDrift(awake, 60.0);
  a.ccd_max_x = CcdMaxX(base);
  return a;
}

// ---------------------------------------------------------------------------------------------
// Step time.

double Median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::sort(v.begin(), v.end());
  const size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// CPU time of the calling thread (ms): what the step costs, less sensitive than wall time to
// other processes on the shared cores.
double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) * 1e3 + static_cast<double>(ts.tv_nsec) * 1e-6;
}

// Steps once; appends the step's wall and thread-CPU milliseconds.
template <typename Scene>
void TimeStep(Scene& s, std::vector<double>* wall, std::vector<double>* cpu) {
  const double c0 = ThreadCpuMs();
  const auto a = std::chrono::steady_clock::now();
  s.Step();
  wall->push_back(
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - a).count());
  cpu->push_back(ThreadCpuMs() - c0);
}

struct SceneFigures {
  double phys_ms = 0, raw_ms = 0;          // wall, median
  double phys_cpu_ms = 0, raw_cpu_ms = 0;  // thread CPU, median
  double moving = 0, raw_moving = 0;   // mean share faster than 1 cm/s
  double frozen = 0;                   // mean share of boxes frozen (rest_freeze)
  double deepest_mm = 0;               // p99 over samples of the deepest contact penetration
  size_t escaped = 0;                  // boxes outside the container at the end
};

// Deepest penetration (mm, positive) among the world's touching contact points.
double DeepestPenetrationMm(btDiscreteDynamicsWorld* w) {
  btDispatcher* d = w->getDispatcher();
  double deepest = 0;
  for (int i = 0; i < d->getNumManifolds(); ++i) {
    const btPersistentManifold* m = d->getManifoldByIndexInternal(i);
    for (int k = 0; k < m->getNumContacts(); ++k) {
      deepest = std::max(deepest, -1000.0 * m->getContactPoint(k).getDistance());
    }
  }
  return deepest;
}

size_t Escaped(PhysicsWorld& w, const MultiObjectParams& p) {
  const float lim = MultiObjectHalfWidth(p) + 0.05f;
  size_t n = 0;
  for (int i = 0; i < p.num_objects; ++i) {
    const Vec3f x = Pos(w, kSceneFirstBoxId + static_cast<uint32_t>(i));
    if (std::abs(x.x) > lim || std::abs(x.z) > lim || x.y < -0.05f) ++n;
  }
  return n;
}

SceneFigures MeasureScene(const MultiObjectParams& p, int warmup, int steps, bool with_raw) {
  PhysSMultiObjectScene phys(p);
  std::unique_ptr<RawBulletMultiObjectScene> raw;
  if (with_raw) raw = std::make_unique<RawBulletMultiObjectScene>(p);
  for (int i = 0; i < warmup; ++i) {
    phys.Step();
    if (raw) raw->Step();
  }
  std::vector<double> pm, rm, pc, rc, deep, mv, rmv, fr;
  for (int i = 0; i < steps; ++i) {
    if (!raw) {
      TimeStep(phys, &pm, &pc);
    } else if (i % 2 == 0) {
      TimeStep(phys, &pm, &pc);
      TimeStep(*raw, &rm, &rc);
    } else {
      TimeStep(*raw, &rm, &rc);
      TimeStep(phys, &pm, &pc);
    }
    if (i % 10 == 0) {
      deep.push_back(DeepestPenetrationMm(phys.world().BulletWorldForTesting()));
      mv.push_back(static_cast<double>(phys.MovingBoxes(0.01f)) / p.num_objects);
      fr.push_back(static_cast<double>(phys.world().counters().frozen_bodies) / p.num_objects);
      if (raw) rmv.push_back(static_cast<double>(raw->MovingBoxes(0.01f)) / p.num_objects);
    }
  }
  auto mean = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0.0 : s / static_cast<double>(v.size());
  };
  SceneFigures f;
  f.phys_ms = Median(pm);
  f.raw_ms = Median(rm);
  f.phys_cpu_ms = Median(pc);
  f.raw_cpu_ms = Median(rc);
  f.moving = mean(mv);
  f.raw_moving = mean(rmv);
  f.frozen = mean(fr);
  std::sort(deep.begin(), deep.end());
  f.deepest_mm = deep.empty() ? 0 : deep[std::min(deep.size() - 1, deep.size() * 99 / 100)];
  f.escaped = Escaped(phys.world(), p);
  return f;
}

std::vector<std::string> Split(const std::string& s) {
  std::vector<std::string> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

int Main(int argc, char** argv) {
  MultiObjectParams p;
  p.num_objects = 2000;
  int warmup = 120, steps = 240;
  std::string only, out = ".", realtime, label = "2,000-box MultiObject";
  bool render = false, accuracy = true, with_raw = true;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "%s needs a value\n", a.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--objects") p.num_objects = std::stoi(next());
    else if (a == "--layers") p.layers = std::stof(next());
    else if (a == "--stirrer-reach") p.stirrer_reach = std::stof(next());
    else if (a == "--stirrer-speed") p.stirrer_angular_speed = std::stof(next());
    else if (a == "--warmup") warmup = std::stoi(next());
    else if (a == "--steps") steps = std::max(10, std::stoi(next()));
    else if (a == "--only") only = next();
    else if (a == "--out") out = next();
    else if (a == "--render") render = true;
    else if (a == "--no-accuracy") accuracy = false;
    else if (a == "--no-raw") with_raw = false;  // PhyS only (profiling)
    else if (a == "--realtime") realtime = next();
    else if (a == "--label") label = next();  // the scene, in the chart's title
    else if (a == "--suite-substep") g_suite_substep_s = std::stod(next());
    else {
      std::fprintf(stderr,
                   "usage: physics_cost_report [--objects N] [--layers L] [--stirrer-reach F] "
                   "[--stirrer-speed W] [--warmup N] [--steps N] [--only a,b] [--out DIR] "
                   "[--render] [--no-accuracy] [--no-raw] [--label TEXT] [--realtime N,N,...] "
                   "[--suite-substep SECONDS]\n");
      return 2;
    }
  }
  if (!realtime.empty()) {
    std::printf("objects,phys_wall_ms,raw_wall_ms,phys_cpu_ms,raw_cpu_ms,ratio_cpu,"
                "realtime_factor_wall,moving,frozen\n");
    for (const std::string& n : Split(realtime)) {
      MultiObjectParams q = p;
      q.num_objects = std::stoi(n);
      const SceneFigures f = MeasureScene(q, warmup, steps, true);
      std::printf("%d,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f\n", q.num_objects, f.phys_ms,
                  f.raw_ms, f.phys_cpu_ms, f.raw_cpu_ms, f.phys_cpu_ms / f.raw_cpu_ms,
                  (1000.0 / 60.0) / f.phys_ms, f.moving, f.frozen);
      std::fflush(stdout);
    }
    return 0;
  }
  std::ofstream dat(out + "/physics_cost.dat");
  dat << "# index candidate ratio_cpu phys_cpu_ms raw_cpu_ms stack_drift_m pass bounce_worst "
         "friction_worst ccd_max_x awake_m deepest_mm escaped moving raw_moving phys_wall_ms "
         "raw_wall_ms ratio_wall sim_s_ratio\n";
  std::printf("candidate,phys_cpu_ms,raw_cpu_ms,ratio_cpu,phys_wall_ms,raw_wall_ms,ratio_wall,"
              "moving,raw_moving,frozen,deepest_mm,escaped,freefall_err_m,bounce_worst,"
              "friction_worst,stack_drift_m,stack_awake_m,ccd_max_x,suite,sim_s_ratio\n");
  const std::vector<std::string> wanted = Split(only);
  int index = 0;
  for (const Candidate& c : Candidates()) {
    if (!wanted.empty() && std::find(wanted.begin(), wanted.end(), c.name) == wanted.end()) continue;
    MultiObjectParams q = p;
    c.apply(q.config);
    const SceneFigures f = MeasureScene(q, warmup, steps, with_raw);
    const Accuracy a = accuracy ? MeasureAccuracy(q.config) : Accuracy{};
    const double ratio = f.raw_cpu_ms > 0 ? f.phys_cpu_ms / f.raw_cpu_ms : 0;
    const double ratio_wall = f.raw_ms > 0 ? f.phys_ms / f.raw_ms : 0;
    // CPU per simulated second: PhyS steps of its fixed_dt against raw Bullet's 1/60 s steps.
    const double sim_s_ratio = ratio * (1.0 / 60.0) / q.config.fixed_dt;
    std::printf("%s,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.3f,%.2f,%zu,%.2e,%.3f,%.3f,%.4f,"
                "%.4f,%.4f,%s,%.3f\n",
                c.name.c_str(), f.phys_cpu_ms, f.raw_cpu_ms, ratio, f.phys_ms, f.raw_ms,
                ratio_wall, f.moving, f.raw_moving, f.frozen, f.deepest_mm, f.escaped, a.freefall_err,
                a.bounce_worst, a.friction_worst, a.stack_drift, a.stack_awake, a.ccd_max_x,
                !accuracy ? "n/a" : a.ok() ? "pass" : "FAIL", sim_s_ratio);
    std::fflush(stdout);
    dat << index++ << " " << c.name << " " << ratio << " " << f.phys_cpu_ms << " "
        << f.raw_cpu_ms << " " << a.stack_drift << " " << (a.ok() ? 1 : 0) << " "
        << a.bounce_worst << " " << a.friction_worst << " " << a.ccd_max_x << " " << a.stack_awake
        << " " << f.deepest_mm << " " << f.escaped << " " << f.moving << " " << f.raw_moving
        << " " << f.phys_ms << " " << f.raw_ms << " " << ratio_wall << " "
        << sim_s_ratio << "\n";
  }
  dat.close();
  chart::Chart ch;
  ch.stem = "physics_cost";
  ch.dir = out;
  ch.layout = chart::Layout::kLoopScript;
  ch.terminals = chart::ReportTerminals(900, 520);
  ch.comment = "Generated by physics_cost_report; run in the output directory.";
  ch.body = "  set title \"PhyS settings, " + label +
            ": step time vs accuracy (the accuracy suite at each setting)\"\n" + R"GP(
  set xlabel "PhyS step CPU time / raw Bullet at its defaults (same run, medians)"
  set ylabel "never-sleeping ten-box stack: drift over 60 s (m, log)"
  set logscale y
  set yrange [0.005:30]
  set xrange [0.45:1.25]
  set grid
  set key bottom center
  set arrow from 0.5, graph 0 to 0.5, graph 1 nohead dt 2 lc rgb "#888888"
  set label "target 0.5x" at 0.505, graph 0.95 left font "sans,8"
  set arrow from graph 0, first 0.25 to graph 1, first 0.25 nohead dt 2 lc rgb "#888888"
  set label "suite bound 0.25 m" at graph 0.75, first 0.3 left font "sans,8"
  plot "physics_cost.dat" using 3:($7 == 1 ? $11 : 1/0) with points pt 7 ps 1.3 lc rgb "#1f77b4" title "accuracy suite passes", \
       "physics_cost.dat" using 3:($7 == 0 ? $11 : 1/0) with points pt 2 ps 1.6 lc rgb "#d62728" title "suite fails", \
       "physics_cost.dat" using 3:11:2 with labels offset 0.5,0.5 left font "sans,7" rotate by 20 notitle
)GP";
  if (!chart::Write(ch)) {
    std::fprintf(stderr, "cannot write %s/physics_cost.gp\n", out.c_str());
    return 2;
  }
  if (render && !chart::Render(ch)) return 1;
  return 0;
}

}  // namespace
}  // namespace edgephys::physics

int main(int argc, char** argv) { return edgephys::physics::Main(argc, argv); }
