// display_policy_report: which send policy shows receivers the truth for the fewest updates?
// An offline model for issue 15, item 2 ("Velocities on the wire where they pay"), built to decide
// before changing the relay whether a policy can beat today's fixed ambient rate.
//
// It records the multiobject scene's box trajectories at PhyS's 60 Hz (PhysSMultiObjectScene,
// the scene edgephys-loadgen multiobject spawns; after `--warmup` settling steps) and replays
// each send policy over them, box by box:
//   * fixed F Hz (today's ambient class): a box is sampled every 60/F ticks (a random phase per
//     box), and only if it moved beyond the selective-sync thresholds (1 mm / 0.1 deg) from the
//     last sample;
//   * key samples at T mm (format 2 unchanged, no velocities): a box is sampled when the straight
//     line (lerp/slerp) from its last sample to its state now strays from one of its states in
//     between by more than T (or by T/10 rad in rotation), or when `--max-interval` passed while
//     it moved; the sample is its state of this tick (what the relay can send without keeping
//     older states).
// A receiver shows, at every tick, the lerp/slerp between the two samples around it (the SDK's
// interpolation; playout delay is not an error here: like the loadgen's display probe, the
// display is compared with the truth at the displayed time). Every box counts, resting or not.
// Quantisation (1 mm) and loss are not modelled; egress is modelled as samples x the bytes per
// update that `multiobject` measured for format 2 at 6 Hz (--bytes-per-update).
//
//   display_policy_report [--objects 1000] [--layers 3] [--stirrer-reach 0.95]
//       [--stirrer-speed 1.5] [--warmup 120] [--seconds 8] [--max-interval 1.0]
//       [--bytes-per-update 6.74] [--paper-mbit 1.32]
// Prints CSV: policy, samples per box per s, modelled ratio to the paper, display p50/p99 (mm),
// rotation p99 (deg).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "physics/scenes.h"

namespace edgephys::physics {
namespace {

struct Pose {
  Vec3f p;
  Quatf q;
};

double Dist(const Vec3f& a, const Vec3f& b) {
  const double dx = a.x - b.x, dy = a.y - b.y, dz = a.z - b.z;
  return std::sqrt(dx * dx + dy * dy + dz * dz);
}
double AngleRad(const Quatf& a, const Quatf& b) {
  const double d = std::fabs(static_cast<double>(a.x) * b.x + static_cast<double>(a.y) * b.y +
                             static_cast<double>(a.z) * b.z + static_cast<double>(a.w) * b.w);
  return 2.0 * std::acos(std::min(1.0, d));
}
Pose Lerp(const Pose& a, const Pose& b, double t) {
  Pose r;
  r.p = {static_cast<float>(a.p.x + (b.p.x - a.p.x) * t), static_cast<float>(a.p.y + (b.p.y - a.p.y) * t),
         static_cast<float>(a.p.z + (b.p.z - a.p.z) * t)};
  // nlerp on the shorter arc: within a fraction of a degree of slerp at these angles.
  double s = a.q.x * b.q.x + a.q.y * b.q.y + a.q.z * b.q.z + a.q.w * b.q.w;
  const double sign = s < 0 ? -1.0 : 1.0;
  double x = a.q.x + (sign * b.q.x - a.q.x) * t, y = a.q.y + (sign * b.q.y - a.q.y) * t;
  double z = a.q.z + (sign * b.q.z - a.q.z) * t, w = a.q.w + (sign * b.q.w - a.q.w) * t;
  const double n = std::sqrt(x * x + y * y + z * z + w * w);
  r.q = {static_cast<float>(x / n), static_cast<float>(y / n), static_cast<float>(z / n), static_cast<float>(w / n)};
  return r;
}
double Percentile(std::vector<double> v, double pct) {
  if (v.empty()) return 0;
  const size_t k = std::min(v.size() - 1, static_cast<size_t>(pct / 100.0 * static_cast<double>(v.size())));
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(k), v.end());
  return v[k];
}
bool Moved(const Pose& a, const Pose& b) {
  return Dist(a.p, b.p) > 0.001 || AngleRad(a.q, b.q) > 0.1 * M_PI / 180.0;
}

struct Outcome {
  double samples = 0;                       // over all boxes
  std::vector<double> err_mm, rot_deg;      // every box, every tick with samples on both sides
};

// The display error of one box's samples (tick indices, ascending, the first at tick 0).
void Score(const std::vector<Pose>& truth, const std::vector<size_t>& samples, Outcome* out) {
  out->samples += static_cast<double>(samples.size());
  for (size_t s = 0; s + 1 < samples.size(); ++s) {
    const size_t a = samples[s], b = samples[s + 1];
    for (size_t j = a; j < b; ++j) {
      const Pose shown = Lerp(truth[a], truth[b], static_cast<double>(j - a) / static_cast<double>(b - a));
      out->err_mm.push_back(Dist(shown.p, truth[j].p) * 1000.0);
      out->rot_deg.push_back(AngleRad(shown.q, truth[j].q) * 180.0 / M_PI);
    }
  }
}

std::vector<size_t> FixedRate(const std::vector<Pose>& truth, int every, int phase) {
  std::vector<size_t> s = {0};
  for (size_t j = static_cast<size_t>(phase); j < truth.size(); j += static_cast<size_t>(every)) {
    if (j > 0 && Moved(truth[s.back()], truth[j])) s.push_back(j);
  }
  // The display needs a sample after the window to interpolate its end: the state at the end.
  if (s.back() != truth.size() - 1) s.push_back(truth.size() - 1);
  return s;
}

std::vector<size_t> KeySamples(const std::vector<Pose>& truth, double threshold_m, size_t max_gap) {
  std::vector<size_t> s = {0};
  const double rot_threshold = threshold_m * 10.0;  // 10 mm ~ 0.1 rad (5.7 deg)
  for (size_t b = 1; b < truth.size(); ++b) {
    const size_t a = s.back();
    bool stray = false;
    for (size_t j = a + 1; j < b && !stray; ++j) {
      const Pose line = Lerp(truth[a], truth[b], static_cast<double>(j - a) / static_cast<double>(b - a));
      stray = Dist(line.p, truth[j].p) > threshold_m || AngleRad(line.q, truth[j].q) > rot_threshold;
    }
    if (stray || (b - a >= max_gap && Moved(truth[a], truth[b]))) s.push_back(b);
  }
  if (s.back() != truth.size() - 1) s.push_back(truth.size() - 1);
  return s;
}

// Key samples at the kink: when the line from the last sample a to the state now (b) strays,
// the sample is the state in between that lies furthest from the line (the kink, at its own
// time: the relay's recent states hold it), not the state now; the line from the kink to b is
// checked again at once (it may need a kink of its own). `lookback` bounds how far back the
// kink may lie (the relay's recent states: Entity::kRecentStates).
std::vector<size_t> KinkSamples(const std::vector<Pose>& truth, double threshold_m, size_t max_gap,
                                size_t lookback) {
  std::vector<size_t> s = {0};
  const double rot_threshold = threshold_m * 10.0;
  for (size_t b = 1; b < truth.size(); ++b) {
    for (;;) {
      const size_t a = s.back();
      size_t worst = 0;
      double worst_excess = 0;
      bool stray = false;
      for (size_t j = a + 1; j < b; ++j) {
        const Pose line = Lerp(truth[a], truth[b], static_cast<double>(j - a) / static_cast<double>(b - a));
        const double excess = std::max(Dist(line.p, truth[j].p) / threshold_m,
                                       AngleRad(line.q, truth[j].q) / rot_threshold);
        stray = stray || excess > 1.0;
        if (excess > 1.0 && excess > worst_excess && b - j <= lookback) {
          worst_excess = excess;
          worst = j;
        }
      }
      if (worst == 0) {
        if (stray) s.push_back(b);  // the kink is older than the states kept: the state now
        break;
      }
      s.push_back(worst);
    }
    const size_t a = s.back();
    if (b - a >= max_gap && Moved(truth[a], truth[b])) s.push_back(b);
  }
  if (s.back() != truth.size() - 1) s.push_back(truth.size() - 1);
  return s;
}

const char* Arg(int argc, char** argv, const char* name, const char* fallback) {
  for (int i = 1; i + 1 < argc; ++i) {
    if (std::strcmp(argv[i], name) == 0) return argv[i + 1];
  }
  return fallback;
}

}  // namespace
}  // namespace edgephys::physics

int main(int argc, char** argv) {
  using namespace edgephys;
  using namespace edgephys::physics;
  MultiObjectParams p;
  p.num_objects = std::atoi(Arg(argc, argv, "--objects", "1000"));
  p.layers = static_cast<float>(std::atof(Arg(argc, argv, "--layers", "3")));
  p.stirrer_reach = static_cast<float>(std::atof(Arg(argc, argv, "--stirrer-reach", "0.95")));
  p.stirrer_angular_speed = static_cast<float>(std::atof(Arg(argc, argv, "--stirrer-speed", "1.5")));
  p.config.sleep_linear_threshold = p.config.sleep_angular_threshold = 0.1f;  // as multiobject
  const int warmup = std::atoi(Arg(argc, argv, "--warmup", "120"));
  const double seconds = std::atof(Arg(argc, argv, "--seconds", "8"));
  const double max_interval = std::atof(Arg(argc, argv, "--max-interval", "1.0"));
  const double bytes_per_update = std::atof(Arg(argc, argv, "--bytes-per-update", "6.74"));
  const double paper_mbit = std::atof(Arg(argc, argv, "--paper-mbit", "1.32"));
  if (p.num_objects <= 0 || seconds <= 0 || max_interval <= 0) {
    std::fprintf(stderr, "bad arguments\n");
    return 2;
  }
  PhysSMultiObjectScene scene(p);
  for (int i = 0; i < warmup; ++i) scene.Step();
  const size_t ticks = static_cast<size_t>(seconds * 60.0);
  const size_t n = static_cast<size_t>(p.num_objects);
  std::vector<std::vector<Pose>> truth(n, std::vector<Pose>(ticks));
  for (size_t t = 0; t < ticks; ++t) {
    scene.Step();
    for (size_t k = 0; k < n; ++k) {
      EntityState st;
      (void)scene.world().GetState(kSceneFirstBoxId + static_cast<uint32_t>(k), &st);
      truth[k][t] = {st.position, st.rotation};
    }
  }
  std::printf("policy,samples_per_box_per_s,modelled_ratio_to_paper,display_p50_mm,display_p99_mm,"
              "rotation_p99_deg\n");
  auto report = [&](const std::string& name, const Outcome& o) {
    const double per_box_s = o.samples / static_cast<double>(n) / seconds;
    const double mbit = per_box_s * static_cast<double>(n) * bytes_per_update * 8 / 1e6;
    std::printf("%s,%.3f,%.3f,%.2f,%.2f,%.2f\n", name.c_str(), per_box_s, mbit / paper_mbit,
                Percentile(o.err_mm, 50), Percentile(o.err_mm, 99), Percentile(o.rot_deg, 99));
  };
  std::mt19937 rng(7);
  for (int hz : {12, 6, 4, 3}) {
    Outcome o;
    for (size_t k = 0; k < n; ++k) {
      const int every = 60 / hz;
      Score(truth[k], FixedRate(truth[k], every, static_cast<int>(rng() % static_cast<unsigned>(every))), &o);
    }
    report("fixed " + std::to_string(hz) + " Hz", o);
  }
  const size_t max_gap = static_cast<size_t>(max_interval * 60.0);
  for (double mm : {5.0, 10.0, 15.0, 20.0, 30.0}) {
    Outcome o;
    for (size_t k = 0; k < n; ++k) Score(truth[k], KeySamples(truth[k], mm / 1000.0, max_gap), &o);
    char name[64];
    std::snprintf(name, sizeof(name), "key samples %.0f mm", mm);
    report(name, o);
  }
  for (double mm : {10.0, 15.0, 20.0, 30.0, 40.0, 50.0}) {
    Outcome o;
    for (size_t k = 0; k < n; ++k) Score(truth[k], KinkSamples(truth[k], mm / 1000.0, max_gap, 30), &o);
    char name[64];
    std::snprintf(name, sizeof(name), "key samples at the kink %.0f mm", mm);
    report(name, o);
  }
  return 0;
}
