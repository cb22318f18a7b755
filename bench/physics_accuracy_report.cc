// physics_accuracy_report: headless accuracy and stability report for PhyS (PhysicsWorld on
// Bullet). A plain executable (not Google Benchmark): for each experiment it prints a CSV block
// to stdout and writes a whitespace-separated .dat file plus a gnuplot script into --out; with
// --render it also runs gnuplot there, producing physics_*.png and physics_*.svg.
//
//   physics_accuracy_report --out DIR [--render] [--only freefall,bounce,...]
//
// Experiments (names for --only):
//   freefall  height vs time (PhyS, symplectic Euler prediction, 0.5 g t^2) and error vs dt
//   bounce    apex heights per bounce for e = 0.5 / 0.8 (1 and 4 substeps) vs h0 e^(2n)
//   friction  cube under tilted gravity (= slope), mu 0.5: displacement after 2 s and
//             measured acceleration vs g (sin - mu cos) around atan(mu)
//   stack     10-box stack, top-box drift over 60 s for several substep / sleeping settings
//   ccd       50 m/s sphere (r 5 cm) against walls of varying thickness, CCD on / off
//   soft      soft-body stability envelope: stiffness x dt x iterations, guard resets
//   speed     step time (1,000-box MultiObject, median) vs stack drift after 10 s for
//             solver iterations {4,10,20} x substeps {1,2,4}
//
// Everything except `speed` is deterministic. Runtime on the 2-core VM: about 12 s,
#include <BulletSoftBody/btSoftBody.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "bench/accuracy_report.h"
#include "loadgen/chart.h"
#include "physics_backend/container_builder.h"
#include "physics_backend/physics_world.h"
#include "physics_backend/testing/physics_probes.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {

// ---------------------------------------------------------------------------------------------
// (6) Soft-body stability envelope: 5x5x5 lattice cube (125 particles of 10 g, 5 cm spacing,
// 26-neighbour springs) dropped from 0.3 m, 2 simulated seconds, kLST unclamped.

struct SoftCell {
  double klst = 0;          // k dt^2 2 / m (unclamped)
  uint64_t resets = 0;
  uint64_t late_resets = 0;  // in the last 0.5 s
  uint64_t softened = 0;
  int first_reset_step = -1;
  bool non_finite_seen = false;  // NaN/inf reached the caller (CollectStates or nodes)
  double extent_ratio = 0;       // final AABB diagonal / initial
  double max_extent_ratio = 0;   // over the run, as seen after each Step()
  int cls = 0;  // 0 stable, 1 exploded and recovered, 2 still resetting, 3 failed
};

SoftCell RunSoftCell(float k, int hz, int iterations, float max_link) {
  PhysicsConfig cfg;
  cfg.fixed_dt = 1.0f / static_cast<float>(hz);
  cfg.soft_iterations = iterations;
  cfg.soft_max_link_stiffness = max_link;
  PhysicsWorld world(cfg);
  AddSpec(world, testing::Ground(1, 0.5f, 0.0f));
  EntitySpec e;
  e.id = 2;
  e.soft_body = MakeLatticeCubeSoftBody(k);
  AddSpec(world, e);
  SoftCell c;
  const double dt = cfg.fixed_dt;
  c.klst = k * dt * dt * 2.0 / 0.01;
  const double diag0 = std::sqrt(3.0) * 0.2;
  const int steps = 2 * hz;
  std::vector<Vec3f> nodes;
  std::vector<EntityState> moved;
  std::vector<PhysicsEvent> events;
  for (int i = 1; i <= steps; ++i) {
    world.Step();
    world.CollectStates(&moved);
    for (const EntityState& s : moved) c.non_finite_seen |= !IsValidState(s);
    events.clear();
    world.DrainEvents(&events);
    for (const PhysicsEvent& ev : events) {
      if (ev.type != PhysicsEventType::kGuardReset) continue;
      if (c.first_reset_step < 0) c.first_reset_step = i;
      if (i > steps - hz / 2) ++c.late_resets;
    }
    (void)world.GetSoftBodyNodes(2, &nodes);
    Vec3f mn{1e30f, 1e30f, 1e30f}, mx{-1e30f, -1e30f, -1e30f};
    for (const Vec3f& p : nodes) {
      c.non_finite_seen |= !(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
      mn = {std::min(mn.x, p.x), std::min(mn.y, p.y), std::min(mn.z, p.z)};
      mx = {std::max(mx.x, p.x), std::max(mx.y, p.y), std::max(mx.z, p.z)};
    }
    c.extent_ratio = Distance(mn, mx) / diag0;
    c.max_extent_ratio = std::max(c.max_extent_ratio, c.extent_ratio);
  }
  c.resets = world.counters().guard_resets;
  c.softened = world.counters().soft_softened;
  if (c.non_finite_seen || c.max_extent_ratio >= cfg.soft_max_extent_ratio) {
    c.cls = 3;
  } else if (c.resets == 0) {
    c.cls = 0;
  } else {
    c.cls = c.late_resets == 0 ? 1 : 2;
  }
  return c;
}

void RunSoft() {
  const float ks[] = {20, 60, 200, 600, 2000, 6000, 20000};
  const int hzs[] = {240, 120, 60, 30};
  const int iters[] = {1, 4, 10};
  OutFile dat("physics_soft.dat");
  std::printf("\n# soft: 125-particle lattice cube, 2 s, kLST unclamped (soft_max_link_stiffness "
              "1e9); class 0 stable, 1 exploded+recovered, 2 still resetting, 3 failed\n");
  std::printf("iterations,stiffness_N_m,dt_s,klst,resets,late_resets,softened,first_reset_step,"
              "max_extent_ratio,final_extent_ratio,non_finite_seen,class\n");
  int counts[4] = {0, 0, 0, 0};
  int block = 0;
  for (int it : iters) {
    dat.Printf("# block %d: iterations %d: k_index dt_index k dt klst resets softened class "
               "max_extent\n", block++, it);
    for (size_t di = 0; di < std::size(hzs); ++di) {
      for (size_t ki = 0; ki < std::size(ks); ++ki) {
        const SoftCell c = RunSoftCell(ks[ki], hzs[di], it, 1e9f);
        ++counts[c.cls];
        dat.Printf("%zu %zu %.0f %.6f %.4g %llu %llu %d %.3f\n", ki, di, ks[ki], 1.0 / hzs[di],
                   c.klst, static_cast<unsigned long long>(c.resets),
                   static_cast<unsigned long long>(c.softened), c.cls, c.max_extent_ratio);
        std::printf("%d,%.0f,%.5f,%.4g,%llu,%llu,%llu,%d,%.3f,%.3f,%d,%d\n", it, ks[ki],
                    1.0 / hzs[di], c.klst, static_cast<unsigned long long>(c.resets),
                    static_cast<unsigned long long>(c.late_resets),
                    static_cast<unsigned long long>(c.softened), c.first_reset_step,
                    c.max_extent_ratio, c.extent_ratio, c.non_finite_seen ? 1 : 0, c.cls);
      }
      dat.Printf("\n");
    }
    dat.Printf("\n");
  }
  std::printf("# soft summary (unclamped): stable %d, exploded+recovered %d, still resetting %d,"
              " failed %d\n", counts[0], counts[1], counts[2], counts[3]);
  // Same grid with the default clamp (kLST <= 1), 4 and 10 iterations.
  std::printf("\n# soft_clamped: default soft_max_link_stiffness = 1\n");
  std::printf("iterations,stiffness_N_m,dt_s,klst_unclamped,resets,class\n");
  int clamped_resets = 0;
  for (int it : {4, 10}) {
    for (int hz : hzs) {
      for (float k : ks) {
        const SoftCell c = RunSoftCell(k, hz, it, 1.0f);
        clamped_resets += static_cast<int>(c.resets);
        std::printf("%d,%.0f,%.5f,%.4g,%llu,%d\n", it, k, 1.0 / hz, c.klst,
                    static_cast<unsigned long long>(c.resets), c.cls);
      }
    }
  }
  std::printf("# soft_clamped summary: total guard resets %d\n", clamped_resets);
  WriteGnuplot("physics_soft_envelope", 1200, 400, R"GP(
  set multiplot layout 1,3 title "Soft-body stability envelope: 125-particle lattice, kLST unclamped, 2 s. Green: stable; orange: exploded, guard reset and recovered. Cell: resets / kLST"
  set palette defined (0 "#9ad39a", 1 "#f7c46c", 2 "#e8853d", 3 "#d9453a")
  set cbrange [-0.5:3.5]; unset colorbox
  set xrange [-0.5:6.5]; set yrange [-0.5:3.5]
  set xtics ("20" 0, "60" 1, "200" 2, "600" 3, "2k" 4, "6k" 5, "20k" 6)
  set ytics ("1/240" 0, "1/120" 1, "1/60" 2, "1/30" 3)
  set xlabel "spring stiffness (N/m)"; set ylabel "dt (s)"
  do for [b=0:2] {
    set title sprintf("soft solver iterations = %d", b == 0 ? 1 : (b == 1 ? 4 : 10))
    plot "physics_soft.dat" index b using 1:2:8 with image notitle, \
         "" index b using 1:2:(sprintf($5 < 10 ? "%d\n%.2f" : "%d\n%.0f", $6, $5)) with labels font "sans,7" notitle
  }
)GP");
}

// ---------------------------------------------------------------------------------------------
// (7) Step time vs accuracy.

void RunSpeed(int warmup, int measured) {
  OutFile dat("physics_speed_accuracy.dat");
  dat.Printf("# iterations substeps cpu_ms_median wall_ms_median wall_ms_p90 stack_drift_10s_m"
             " bounce_worst_rel_err_e0.8 label\n");
  std::printf("\n# speed: MultiObject 1000 boxes (PhysSMultiObjectScene, defaults + iterations/"
              "substeps), %d warm-up steps, median of %d steps; stack drift after 10 s (sleep "
              "0.8/1.0 as in the stack test)\n", warmup, measured);
  std::printf("iterations,substeps,cpu_ms_per_step_median,wall_ms_per_step_median,wall_ms_p10,"
              "wall_ms_p90,moving_boxes,stack_drift_10s_m,bounce_worst_rel_err_e0.8\n");
  for (int it : {4, 10, 20}) {
    for (int sub : {1, 2, 4}) {
      MultiObjectParams p;
      p.num_objects = 1000;
      p.config.solver_iterations = it;
      p.config.substeps = sub;
      std::vector<double> ms, cpu;
      size_t moving = 0;
      {
        PhysSMultiObjectScene scene(p);
        for (int i = 0; i < warmup; ++i) scene.Step();
        for (int i = 0; i < measured; ++i) {
          const double c0 = ThreadCpuMs();
          const auto t0 = std::chrono::steady_clock::now();
          scene.Step();
          const auto t1 = std::chrono::steady_clock::now();
          cpu.push_back(ThreadCpuMs() - c0);
          ms.push_back(std::chrono::duration<double, std::milli>(t1 - t0).count());
        }
        moving = scene.MovingBoxes(0.05f);
      }
      std::vector<double> sorted = ms;
      std::sort(sorted.begin(), sorted.end());
      const double p10 = sorted[sorted.size() / 10];
      const double p90 = sorted[sorted.size() * 9 / 10];
      const StackSetting s{"", sub, it, true, 0.8f, 1.0f};
      const StackRun st = Stack(s, 10.0, nullptr, 1);
      // Worst apex-ratio error for e = 0.8 (apexes >= 10 cm), same setting.
      double worst = 0;
      const std::vector<double> h = BounceApexes(sub, 0.8f, 2.0f, 4, 0.1, it);
      for (size_t i = 1; i < h.size(); ++i) {
        worst = std::max(worst, std::abs(h[i] / h[i - 1] - 0.64) / 0.64);
      }
      const double med = Median(ms);
      const double cpu_med = Median(cpu);
      dat.Printf("%d %d %.3f %.3f %.3f %.6e %.4f it%d/sub%d\n", it, sub, cpu_med, med, p90,
                 st.max_drift, worst, it, sub);
      std::printf("%d,%d,%.3f,%.3f,%.3f,%.3f,%zu,%.4e,%.3f\n", it, sub, cpu_med, med, p10, p90,
                  moving, st.max_drift, worst);
      std::fflush(stdout);
    }
  }
  WriteGnuplot("physics_speed_accuracy", 820, 460, R"GP(
  set title "Speed vs accuracy: solver iterations x substeps (1,000-box MultiObject step time; 10-box stack drift after 10 s)"
  set grid; set logscale y; set format y "%g"
  set xlabel "PhyS step time: median thread CPU ms per 1/60 s step (1,000-box MultiObject)"
  set ylabel "10-box stack max drift after 10 s (m)"
  set key top right; set offsets graph 0.05, graph 0.12, graph 0.1, graph 0.1
  plot "physics_speed_accuracy.dat" using 3:($2 == 1 ? $6 : 1/0) with points pt 7 ps 1.4 title "1 substep", \
       "" using 3:($2 == 2 ? $6 : 1/0) with points pt 5 ps 1.4 title "2 substeps", \
       "" using 3:($2 == 4 ? $6 : 1/0) with points pt 9 ps 1.6 title "4 substeps", \
       "" using 3:6:8 with labels offset 0,1.1 font "sans,8" notitle, \
       0.01 with lines dt 2 lc rgb "black" title "1 cm"
)GP");
}

bool Wanted(const std::string& only, const char* name) {
  if (only.empty()) return true;
  std::stringstream ss(only);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item == name) return true;
  }
  return false;
}

}  // namespace edgephys::physics

int main(int argc, char** argv) {
  using namespace edgephys::physics;
  std::string only;
  bool render = false;
  int warmup = 60, measured = 60;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--out" && i + 1 < argc) {
      g_out = argv[++i];
    } else if (a == "--only" && i + 1 < argc) {
      only = argv[++i];
    } else if (a == "--render") {
      render = true;
    } else if (a == "--measured-steps" && i + 1 < argc) {
      measured = std::max(30, std::atoi(argv[++i]));
    } else if (a == "--warmup-steps" && i + 1 < argc) {
      warmup = std::max(0, std::atoi(argv[++i]));
    } else {
      std::fprintf(stderr,
                   "usage: %s [--out DIR] [--render] [--only freefall,bounce,friction,stack,ccd,"
                   "soft,speed] [--warmup-steps N] [--measured-steps N>=30]\n",
                   argv[0]);
      return a == "--help" ? 0 : 2;
    }
  }
  struct Section {
    const char* name;
    const char* chart;
    void (*run)();
  };
  static int s_warmup, s_measured;
  s_warmup = warmup;
  s_measured = measured;
  const Section sections[] = {
      {"freefall", "physics_freefall", RunFreeFall},
      {"bounce", "physics_bounce", RunBounce},
      {"friction", "physics_friction", RunFriction},
      {"stack", "physics_stack", RunStack},
      {"ccd", "physics_ccd", RunCcd},
      {"soft", "physics_soft_envelope", RunSoft},
      {"speed", "physics_speed_accuracy", [] { RunSpeed(s_warmup, s_measured); }},
  };
  const auto start = std::chrono::steady_clock::now();
  for (const Section& s : sections) {
    if (!Wanted(only, s.name)) continue;
    const auto t0 = std::chrono::steady_clock::now();
    s.run();
    std::fflush(stdout);
    const double sec =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::fprintf(stderr, "[%s] %.1f s\n", s.name, sec);
    if (render) {
      if (!edgephys::chart::Render(ReportChart(s.chart))) {
        std::fprintf(stderr, "gnuplot failed for %s\n", s.chart);
      }
    }
  }
  std::fprintf(stderr, "total %.1f s\n",
               std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  return 0;
}
