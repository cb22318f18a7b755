// physics_accuracy_report's rigid-body experiments: free fall, restitution, friction, the
// ten-box stack and CCD (bench/accuracy_report.h; the report's header explains each).
#include <BulletSoftBody/btSoftBody.h>
#include <btBulletDynamicsCommon.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "bench/accuracy_report.h"
#include "physics_backend/container_builder.h"

namespace edgephys::physics {

// ---------------------------------------------------------------------------------------------
// (1) Free fall.

struct FallRun {
  double dt = 0;
  double final_err_analytic = 0;     // |y - (-0.5 g t^2)| at t = 2 s
  double bound = 0;                  // 0.5 g dt t: symplectic Euler's exact offset
  double max_err_symplectic = 0;     // max |y - symplectic prediction| (float rounding)
};

FallRun FreeFall(int hz, double seconds, OutFile* trace) {
  PhysicsConfig cfg;
  cfg.fixed_dt = 1.0f / static_cast<float>(hz);
  PhysicsWorld world(cfg);
  AddSpec(world, DynamicSphere(1, {0, 0, 0}, 0.1f, 1.0f));
  const double dt = cfg.fixed_dt;
  const int steps = static_cast<int>(std::lround(seconds * hz));
  FallRun r;
  r.dt = dt;
  if (trace) trace->Printf("%.5f %.6f %.6f %.6f\n", 0.0, 0.0, 0.0, 0.0);
  for (int n = 1; n <= steps; ++n) {
    world.Step();
    const double y = Pos(world, 1).y;
    const double t = dt * n;
    // Semi-implicit Euler: v_n = -g n dt, y_n = y_{n-1} + v_n dt = -g dt^2 n (n + 1) / 2.
    const double pred = -kG * dt * dt * n * (n + 1) / 2.0;
    const double analytic = -0.5 * kG * t * t;
    r.max_err_symplectic = std::max(r.max_err_symplectic, std::abs(y - pred));
    if (trace) trace->Printf("%.5f %.6f %.6f %.6f\n", t, y, pred, analytic);
  }
  const double t = dt * steps;
  r.final_err_analytic = std::abs(Pos(world, 1).y - (-0.5 * kG * t * t));
  r.bound = 0.5 * kG * dt * t;
  return r;
}

void RunFreeFall() {
  {
    OutFile trace("physics_freefall_trace.dat");
    trace.Printf("# dt = 1/60 s: t  y_phys  y_symplectic_euler  y_analytic (m)\n");
    FreeFall(60, 2.0, &trace);
  }
  OutFile dat("physics_freefall_dt.dat");
  dat.Printf("# dt  final_err_vs_analytic  bound_0.5g_dt_t  max_err_vs_symplectic (m), t = 2 s\n");
  std::printf("\n# freefall: 2 s from rest, sphere, no ground\n");
  std::printf("dt_s,final_err_vs_analytic_m,bound_0.5g_dt_t_m,ratio_to_bound,max_err_vs_symplectic_m\n");
  double prev = 0;
  for (int hz : {15, 30, 60, 120, 240, 480, 960}) {
    const FallRun r = FreeFall(hz, 2.0, nullptr);
    dat.Printf("%.6f %.6e %.6e %.6e\n", r.dt, r.final_err_analytic, r.bound,
               r.max_err_symplectic);
    std::printf("%.6f,%.6f,%.6f,%.5f,%.2e", r.dt, r.final_err_analytic, r.bound,
                r.final_err_analytic / r.bound, r.max_err_symplectic);
    if (prev > 0) std::printf("  # halving dt: error ratio %.3f", prev / r.final_err_analytic);
    std::printf("\n");
    prev = r.final_err_analytic;
  }
  WriteGnuplot("physics_freefall", 1200, 380, R"GP(
  set multiplot layout 1,3 title "Free fall from rest, 2 s (PhyS = PhysicsWorld on Bullet 3.24)"
  set grid
  set key top right
  set xlabel "t (s)"; set ylabel "height (m)"
  set title "height, dt = 1/60 s"
  plot "physics_freefall_trace.dat" every 6 using 1:2 with points pt 7 ps 0.6 title "PhyS", \
       "" using 1:3 with lines lw 1.5 title "symplectic Euler prediction", \
       "" using 1:4 with lines dt 2 lw 1.5 title "analytic -g t^2/2"
  set title "deviation from analytic, dt = 1/60 s"
  set ylabel "y - (-g t^2/2)  (mm)"; set key bottom left Left reverse
  plot "physics_freefall_trace.dat" every 4 using 1:(1000*($2-$4)) with points pt 7 ps 0.6 title "PhyS", \
       "" using 1:(1000*($3-$4)) with lines lw 1.5 title "symplectic Euler prediction (= -g dt t / 2)"
  set title "error at t = 2 s vs dt (log-log)"
  set logscale xy; set format y "%.0e"; set format x "%g"
  set xlabel "dt (s)"; set ylabel "|error| (m)"; set key center left Left reverse
  plot "physics_freefall_dt.dat" using 1:2 with linespoints pt 7 title "PhyS vs analytic", \
       "" using 1:3 with lines dt 2 title "0.5 g dt t (slope 1 = O(dt))", \
       "" using 1:4 with linespoints pt 6 title "PhyS vs symplectic prediction (float)"
)GP");
}

// ---------------------------------------------------------------------------------------------
// (2) Restitution.

// The bounce experiment (testing::BounceApexes: apex heights of a sphere dropped from h0 with
// restitution e) with `substeps` and `iterations`, at most 30 s.
std::vector<double> BounceApexes(int substeps, float e, float h0, int max_apexes,
                                 double min_height, int iterations) {
  PhysicsConfig cfg;
  cfg.substeps = substeps;
  cfg.solver_iterations = iterations;
  const testing::BounceRun run =
      testing::BounceApexes(cfg, e, h0, max_apexes, min_height, 60 * 30);
  if (!run.added.ok()) {
    std::fprintf(stderr, "bounce scene: AddEntity failed\n");
    std::exit(2);
  }
  return run.heights;
}

void RunBounce() {
  const float h0 = 2.0f;
  OutFile dat("physics_bounce.dat");
  std::printf("\n# bounce: h0 = 2 m, CCD on, ground restitution 1 (pair = e)\n");
  std::printf("e,substeps,bounce,apex_m,ratio_to_prev,e2,ratio_rel_err,extra_rebound_m_s\n");
  int block = 0;
  for (const int sub : {4, 1}) {
    for (const float e : {0.5f, 0.8f}) {
      const std::vector<double> h = BounceApexes(sub, e, h0, 12, 0.01);
      dat.Printf("# block %d: e = %.1f, substeps = %d: bounce apex_m prediction_m\n", block++, e,
                 sub);
      for (size_t i = 0; i < h.size(); ++i) {
        const double pred = h0 * std::pow(static_cast<double>(e) * e, static_cast<double>(i));
        dat.Printf("%zu %.6f %.6f\n", i, h[i], pred);
        if (i == 0) continue;
        const double ratio = h[i] / h[i - 1];
        const double e2 = static_cast<double>(e) * e;
        // Rebound speed beyond e * impact speed.
        const double extra = std::sqrt(2 * kG * h[i]) - e * std::sqrt(2 * kG * h[i - 1]);
        std::printf("%.1f,%d,%zu,%.4f,%.4f,%.4f,%+.3f,%+.3f\n", e, sub, i, h[i], ratio, e2,
                    (ratio - e2) / e2, extra);
      }
      dat.Printf("\n\n");
    }
  }
  WriteGnuplot("physics_bounce", 900, 420, R"GP(
  set multiplot layout 1,2 title "Bounce apex heights, drop from 2 m (ground restitution 1, CCD on)"
  set grid; set logscale y; set format y "%g"
  set xlabel "bounce n"; set ylabel "apex height (m)"; set key bottom left
  set title "4 substeps (1/240 s)"
  plot "physics_bounce.dat" index 0 using 1:2 with points pt 7 lc 1 title "e = 0.5 PhyS", \
       "" index 0 using 1:3 with lines lc 1 dt 2 title "2 m * e^{2n}", \
       "" index 1 using 1:2 with points pt 5 lc 2 title "e = 0.8 PhyS", \
       "" index 1 using 1:3 with lines lc 2 dt 2 title "2 m * e^{2n}"
  set title "1 substep (1/60 s, default)"
  plot "physics_bounce.dat" index 2 using 1:2 with points pt 7 lc 1 title "e = 0.5 PhyS", \
       "" index 2 using 1:3 with lines lc 1 dt 2 title "2 m * e^{2n}", \
       "" index 3 using 1:2 with points pt 5 lc 2 title "e = 0.8 PhyS", \
       "" index 3 using 1:3 with lines lc 2 dt 2 title "2 m * e^{2n}"
)GP");
}

// ---------------------------------------------------------------------------------------------
// (3) Friction on a slope: a cube (0.2 m, 1 kg) on flat ground with gravity tilted by `angle`.

struct SlopeRun {
  double displacement = 0;  // along the slope after 2 s
  double acceleration = 0;  // (v(1.5 s) - v(0.5 s)) / 1 s
};

SlopeRun Slope(double angle, float mu) {
  PhysicsConfig cfg;
  cfg.gravity = Vec3f{static_cast<float>(kG * std::sin(angle)),
                      static_cast<float>(-kG * std::cos(angle)), 0};
  PhysicsWorld world(cfg);
  AddSpec(world, testing::Ground(1, 1.0f, 0.0f));  // pair friction = 1 * mu
  EntitySpec cube = DynamicBox(2, {0, 0.1f, 0}, {0.1f, 0.1f, 0.1f}, 1.0f);
  cube.rigid_body->friction = mu;
  AddSpec(world, cube);
  SlopeRun r;
  double v_half = 0;
  for (int i = 1; i <= 120; ++i) {
    world.Step();
    if (i == 30) v_half = Vel(world, 2).x;
    if (i == 90) r.acceleration = Vel(world, 2).x - v_half;
  }
  r.displacement = Pos(world, 2).x;
  return r;
}

void RunFriction() {
  const float mu = 0.5f;
  const double crit = std::atan(mu) * 180.0 / kPi;
  OutFile dat("physics_friction.dat");
  dat.Printf("# mu = 0.5, atan(mu) = %.3f deg: angle_deg displacement_2s_m a_measured a_predicted"
             " disp_predicted_m\n", crit);
  std::printf("\n# friction: mu = 0.5 (atan(mu) = %.2f deg), cube 0.2 m, 2 s\n", crit);
  std::printf("angle_deg,displacement_2s_m,a_measured_m_s2,a_predicted_m_s2,a_rel_err\n");
  const double angles[] = {10, 15, 20, 22, 24, 25, 26, 26.5, 27, 27.5, 28, 29, 30, 32,
                           35, 40, 45, 50, 55, 60};
  for (double deg : angles) {
    const double th = deg * kPi / 180.0;
    const SlopeRun r = Slope(th, mu);
    const double a_pred = std::max(0.0, kG * (std::sin(th) - mu * std::cos(th)));
    const double d_pred = 0.5 * a_pred * 4.0;
    dat.Printf("%.2f %.6e %.5f %.5f %.5f\n", deg, r.displacement, r.acceleration, a_pred, d_pred);
    std::printf("%.1f,%.3e,%.4f,%.4f,", deg, r.displacement, r.acceleration, a_pred);
    if (a_pred > 0.05) {
      std::printf("%+.4f\n", (r.acceleration - a_pred) / a_pred);
    } else {
      std::printf("n/a\n");
    }
  }
  char crit_line[64];
  std::snprintf(crit_line, sizeof crit_line, "  crit = %.4f\n", crit);
  WriteGnuplot("physics_friction", 1000, 400, std::string(crit_line) + R"GP(
  set multiplot layout 1,2 title "Friction: cube on a slope, mu = 0.5 (atan(mu) = 26.57 deg)"
  set grid; set xlabel "slope angle (deg)"
  set arrow 1 from crit, graph 0 to crit, graph 1 nohead dt 2 lc rgb "gray40"
  set title "|displacement| after 2 s (log)"
  set logscale y; set format y "%g"; set yrange [1e-6:20]; set ylabel "m"; set key top left
  plot "physics_friction.dat" using 1:(abs($2) > 1e-6 ? abs($2) : 1e-6) with linespoints pt 7 title "PhyS", \
       "" using 1:($5 > 0 ? $5 : 1/0) with lines dt 2 title "0.5 g (sin - mu cos) t^2"
  unset logscale y; set yrange [*:*]; set format y "%g"
  set title "sliding acceleration"; set ylabel "m/s^2"
  plot "physics_friction.dat" using 1:3 with points pt 7 title "PhyS (v(1.5 s) - v(0.5 s))", \
       "" using 1:4 with lines dt 2 title "max(0, g (sin - mu cos))"
)GP");
}

// ---------------------------------------------------------------------------------------------
// (4) Ten-box stack: 0.5 m, 1 kg cubes in exact contact on a static ground (friction 0.5).

StackRun Stack(const StackSetting& s, double seconds, OutFile* series, int sample_every) {
  PhysicsConfig cfg;
  cfg.substeps = s.substeps;
  cfg.solver_iterations = s.iterations;
  cfg.sleeping = s.sleeping;
  cfg.sleep_linear_threshold = s.sleep_lin;
  cfg.sleep_angular_threshold = s.sleep_ang;
  PhysicsWorld world(cfg);
  const testing::BoxStack stack = testing::MakeBoxStack();
  for (const EntitySpec& spec : stack.specs) AddSpec(world, spec);
  const std::vector<Vec3f>& start = stack.start;
  StackRun r;
  const int steps = static_cast<int>(std::lround(seconds / cfg.fixed_dt));
  for (int n = 1; n <= steps; ++n) {
    world.Step();
    for (uint32_t i = 0; i < 10; ++i) {
      r.max_drift = std::max(r.max_drift, Distance(Pos(world, 10 + i), start[i]));
    }
    if (series && n % sample_every == 0) {
      series->Printf("%.3f %.6e %.6e\n", n * cfg.fixed_dt, Distance(Pos(world, 19), start[9]),
                     r.max_drift);
    }
  }
  r.top_drift = Distance(Pos(world, 19), start[9]);
  r.sleeping_end = world.counters().sleeping_bodies;
  return r;
}

void RunStack() {
  const StackSetting settings[] = {
      {"1 substep, sleep 0.1 (defaults)", 1, 10, true, 0.1f, 0.1f},
      {"1 substep, sleep 0.8/1.0", 1, 10, true, 0.8f, 1.0f},
      {"1 substep, no sleeping", 1, 10, false, 0.8f, 1.0f},
      {"4 substeps, sleep 0.1", 4, 10, true, 0.1f, 0.1f},
      {"4 substeps, sleep 0.8/1.0 (test)", 4, 10, true, 0.8f, 1.0f},
      {"4 substeps, no sleeping", 4, 10, false, 0.8f, 1.0f},
  };
  OutFile dat("physics_stack.dat");
  std::printf("\n# stack: 10 x 0.5 m boxes, 60 s, 10 solver iterations, dt 1/60\n");
  std::printf("setting,substeps,sleeping,sleep_thresholds,max_drift_any_box_m,top_drift_end_m,"
              "sleeping_bodies_end,under_1cm\n");
  int block = 0;
  std::string plot = "  plot ";
  for (const StackSetting& s : settings) {
    dat.Printf("# block %d: %s: t_s top_box_drift_m max_drift_so_far_m\n", block, s.name);
    const StackRun r = Stack(s, 60.0, &dat, 6);
    dat.Printf("\n\n");
    std::printf("%s,%d,%d,%.1f/%.1f,%.4e,%.4e,%zu,%s\n", s.name, s.substeps, s.sleeping ? 1 : 0,
                s.sleep_lin, s.sleep_ang, r.max_drift, r.top_drift, r.sleeping_end,
                r.max_drift < 0.01 ? "yes" : "NO");
    char buf[256];
    std::snprintf(buf, sizeof buf,
                  "%s\"physics_stack.dat\" index %d using 1:($2 > 1e-6 ? $2 : 1e-6) with linespoints "
                  "lw 1.5 pt %d pi 50 ps 1.1 title \"%s\"",
                  block ? ", \\\n       " : "", block, block + 4, s.name);
    plot += buf;
    ++block;
  }
  plot += ", \\\n       0.01 with lines dt 2 lc rgb \"black\" title \"1 cm\"\n";
  WriteGnuplot("physics_stack", 820, 440, R"GP(
  set title "10-box stack (0.5 m boxes, 10 iterations, dt 1/60 s): top-box drift over 60 s"
  set grid; set logscale y; set format y "%g"; set yrange [1e-4:100]
  set xlabel "simulated time (s)"; set ylabel "top-box displacement from start (m)"
  set key bottom right font "sans,8" opaque box
)GP" + plot);
}

// ---------------------------------------------------------------------------------------------
// (5) CCD: 50 m/s sphere (r 5 cm, 0.1 kg, no gravity) against a static wall whose front face is
// at x = 1 m, thickness T; 30 steps (0.5 s).

struct CcdRun {
  double final_x = 0;
  double max_x = 0;
};

CcdRun Ccd(double thickness, bool ccd) {
  PhysicsConfig cfg;
  cfg.ccd = ccd;
  PhysicsWorld world(cfg);
  const float half = static_cast<float>(thickness / 2);
  AddSpec(world, StaticBox(1, {1.0f + half, 0, 0}, {half, 1.0f, 1.0f}));
  EntitySpec ball = DynamicSphere(2, {0, 0, 0}, 0.05f, 0.1f);
  ball.rigid_body->use_gravity = false;
  ball.rigid_body->linear_velocity = Vec3f{50.0f, 0, 0};
  AddSpec(world, ball);
  CcdRun r;
  for (int i = 0; i < 30; ++i) {
    world.Step();
    r.max_x = std::max<double>(r.max_x, Pos(world, 2).x);
  }
  r.final_x = Pos(world, 2).x;
  return r;
}

void RunCcd() {
  OutFile dat("physics_ccd.dat");
  dat.Printf("# wall front face x = 1 m: thickness_m final_x_ccd max_x_ccd final_x_noccd "
             "max_x_noccd\n");
  std::printf("\n# ccd: sphere r = 0.05 m at 50 m/s (0.83 m per 1/60 s step), wall face x = 1 m,"
              " 0.5 s\n");
  std::printf("wall_thickness_m,final_x_ccd_m,max_x_ccd_m,penetration_ccd_m,final_x_no_ccd_m,"
              "max_x_no_ccd_m,penetration_no_ccd_m,tunnels_ccd,tunnels_no_ccd\n");
  for (double t : {0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1.0, 1.3, 1.5, 2.0,
                   5.0}) {
    const CcdRun on = Ccd(t, true);
    const CcdRun off = Ccd(t, false);
    dat.Printf("%.4f %.5f %.5f %.5f %.5f\n", t, on.final_x, on.max_x, off.final_x, off.max_x);
    // Tunnelled: ends behind the wall's back face. Penetration: how far the sphere's leading
    // point (r 5 cm) got past the wall's front face (meaningless once tunnelled).
    auto pen = [](const CcdRun& r) { return std::max(0.0, r.max_x + 0.05 - 1.0); };
    std::printf("%.3f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%s,%s\n", t, on.final_x, on.max_x, pen(on),
                off.final_x, off.max_x, pen(off), on.final_x > 1.0 + t ? "YES" : "no",
                off.final_x > 1.0 + t ? "YES" : "no");
  }
  WriteGnuplot("physics_ccd", 800, 420, R"GP(
  set title "50 m/s sphere (r = 5 cm) vs static wall (front face x = 1 m), position after 0.5 s"
  set grid; set logscale xy; set format x "%g"; set format y "%g"
  set xlabel "wall thickness (m)"; set ylabel "sphere centre x after 0.5 s (m)"
  set yrange [0.5:50]; set key center right
  plot "physics_ccd.dat" using 1:2 with linespoints pt 7 lw 1.5 title "CCD on (default)", \
       "" using 1:4 with linespoints pt 5 lw 1.5 title "CCD off", \
       "" using 1:5 with lines dt 3 lc 2 title "CCD off: deepest x reached", \
       0.95 with lines dt 2 lc rgb "black" title "resting against the face (x = 0.95)"
)GP");
}

}  // namespace edgephys::physics
