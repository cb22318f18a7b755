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
//   * key samples on a curve: as key samples, but the receiver draws, and the check
//     tests, the parabola through the sample before the last, the last and the state now (in
//     position; "+rot" also in the rotation's log; "half" bends half as much), built only from
//     samples the receiver holds once the segment's end arrives (no velocities, playout unchanged);
//     the line when the sample before lies more than `--curve-gap-limit` s back. "On the line or
//     a parabola": the relay picks per sample whichever strays least (an unpaid bit a record);
//     "after an interval sample": the parabola only when the last sample came a max interval
//     after the one before it.
// A receiver shows, at every tick, the lerp/slerp between the two samples around it (the SDK's
// interpolation; playout delay is not an error here: like the loadgen's display probe, the
// display is compared with the truth at the displayed time), or the policy's curve; "shown as
// Hermite" draws the line policy's samples as the SDK's kHermite would with every neighbour held
// (tangents from the parabolas through each sample's neighbours). Every box counts, resting or not.
// Quantisation (1 mm) and loss are not modelled; egress is modelled as samples x the bytes per
// update that `multiobject` measured for format 2 at 6 Hz (--bytes-per-update).
//
//   display_policy_report [--objects 1000] [--layers 3] [--stirrer-reach 0.95]
//       [--stirrer-speed 1.5] [--warmup 120] [--seconds 8] [--max-interval 1.0]
//       [--bytes-per-update 6.74] [--paper-mbit 1.32] [--curve-gap-limit 1.0] [--kink]
// Prints CSV: policy, samples per box per s, modelled ratio to the paper, display p50/p99 (mm),
// rotation p99 (deg), key samples sent because the line or curve strayed per box per s (the rest
// at the max interval or the window's end; 0 for other policies). `--kink` adds the "key samples at the kink" rows.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "physics_backend/scenes.h"

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
// Rotation log and exp (short way), for the quadratic in rotation: log(q) = (angle / 2) * axis.
struct V3 {
  double x = 0, y = 0, z = 0;
};
V3 QLog(const Quatf& q) {
  const double s = q.w < 0 ? -1.0 : 1.0;
  const double x = s * q.x, y = s * q.y, z = s * q.z, w = s * q.w;
  const double n = std::sqrt(x * x + y * y + z * z);
  if (n < 1e-12) return {};
  const double k = std::atan2(n, w) / n;
  return {x * k, y * k, z * k};
}
Quatf QExp(const V3& v) {
  const double h = std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
  const double k = h < 1e-9 ? 1.0 : std::sin(h) / h;
  return {static_cast<float>(v.x * k), static_cast<float>(v.y * k), static_cast<float>(v.z * k),
          static_cast<float>(std::cos(h))};
}
Quatf QMul(const Quatf& a, const Quatf& b) {
  return {a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y, a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x,
          a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w, a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z};
}
Quatf QConj(const Quatf& q) { return {-q.x, -q.y, -q.z, q.w}; }

// What a receiver draws between the samples at ticks a and b (a < b) at tick j, a <= j <= b.
//   kLine     lerp/slerp (today);
//   kQuad     the parabola through the sample before a (`prev`, a tick index, or kNoPrev), a and
//             b in position, slerp in rotation; the line if there is no sample before a or it
//             lies more than `gap_limit` ticks before a;
//   kQuadRot  kQuad, and the parabola in the rotation's log relative to a's rotation too;
//   kQuadHalf kQuad with half the parabola's bend (a damped curve: between the line and kQuad).
// The parabola in Newton form: line(a, b) + (t - ta)(t - tb) * the second divided difference.
//   kQuadSmooth kQuad only when the sample before a lies a whole max interval before it (so a
//             was sent for the interval, not for a stray: no kink at a), else the line; the
//             receiver can tell from the gap alone (no bit on the wire).
enum class Curve { kLine, kQuad, kQuadRot, kQuadHalf, kQuadSmooth };
constexpr size_t kNoPrev = static_cast<size_t>(-1);
size_t g_max_gap = 0;  // ticks: the max interval (kQuadSmooth), set once by main

Pose Shown(const std::vector<Pose>& truth, size_t prev, size_t a, size_t b, size_t j, Curve curve,
           size_t gap_limit) {
  const double u = static_cast<double>(j - a) / static_cast<double>(b - a);
  Pose r = Lerp(truth[a], truth[b], u);
  if (curve == Curve::kLine || prev == kNoPrev || prev >= a || a - prev > gap_limit) return r;
  if (curve == Curve::kQuadSmooth && a - prev < g_max_gap) return r;
  const double t0 = static_cast<double>(prev), t1 = static_cast<double>(a), t2 = static_cast<double>(b);
  const double t = static_cast<double>(j);
  const double w = (t - t1) * (t - t2) / (t2 - t0) * (curve == Curve::kQuadHalf ? 0.5 : 1.0);
  const Vec3f& p0 = truth[prev].p;
  const Vec3f& p1 = truth[a].p;
  const Vec3f& p2 = truth[b].p;
  auto bend = [&](double x0, double x1, double x2) {
    return w * ((x2 - x1) / (t2 - t1) - (x1 - x0) / (t1 - t0));
  };
  r.p = {static_cast<float>(r.p.x + bend(p0.x, p1.x, p2.x)), static_cast<float>(r.p.y + bend(p0.y, p1.y, p2.y)),
         static_cast<float>(r.p.z + bend(p0.z, p1.z, p2.z))};
  if (curve == Curve::kQuadRot) {
    const Quatf inv = QConj(truth[a].q);
    const V3 l0 = QLog(QMul(inv, truth[prev].q)), l2 = QLog(QMul(inv, truth[b].q));
    // Line in log space from 0 (at a) to l2, plus the bend through l0.
    const V3 l = {l2.x * u + bend(l0.x, 0, l2.x), l2.y * u + bend(l0.y, 0, l2.y), l2.z * u + bend(l0.z, 0, l2.z)};
    r.q = QMul(truth[a].q, QExp(l));
  }
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
  double strayed = 0;                       // of which sent because the line or curve strayed
  std::vector<double> err_mm, rot_deg;      // every box, every tick with samples on both sides
};

// The display error of one box's samples (tick indices, ascending, the first at tick 0), drawn
// as `curve` (see Shown).
// `per_segment` (if given): the curve of each segment s -> s + 1 instead of `curve`.
void Score(const std::vector<Pose>& truth, const std::vector<size_t>& samples, Outcome* out,
           Curve curve = Curve::kLine, size_t gap_limit = 0,
           const std::vector<Curve>* per_segment = nullptr) {
  out->samples += static_cast<double>(samples.size());
  for (size_t s = 0; s + 1 < samples.size(); ++s) {
    const size_t a = samples[s], b = samples[s + 1];
    const size_t prev = s > 0 ? samples[s - 1] : kNoPrev;
    const Curve c = per_segment != nullptr ? (*per_segment)[s] : curve;
    for (size_t j = a; j < b; ++j) {
      const Pose shown = Shown(truth, prev, a, b, j, c, gap_limit);
      out->err_mm.push_back(Dist(shown.p, truth[j].p) * 1000.0);
      out->rot_deg.push_back(AngleRad(shown.q, truth[j].q) * 180.0 / M_PI);
    }
  }
}

// The same samples drawn as cubic Hermite curves whose tangents are the derivatives of the
// parabolas through each sample and its neighbours (the SDK's Interpolator::kHermite without
// velocities, with every neighbour held: the sample after b too, which a receiver at today's
// key-sample playout often does not hold yet, so this is Hermite's best case); rotation slerp.
void ScoreHermite(const std::vector<Pose>& truth, const std::vector<size_t>& samples, Outcome* out,
                  size_t gap_limit) {
  out->samples += static_cast<double>(samples.size());
  const size_t n = samples.size();
  auto tangent = [&](size_t i, float Vec3f::*c) {  // d/dtick at samples[i]
    auto x = [&](size_t k) { return static_cast<double>(truth[samples[k]].p.*c); };
    auto t = [&](size_t k) { return static_cast<double>(samples[k]); };
    const bool prev = i > 0 && samples[i] - samples[i - 1] <= gap_limit;
    const bool next = i + 1 < n && samples[i + 1] - samples[i] <= gap_limit;
    if (prev && next) {
      const double t0 = t(i - 1) - t(i), t2 = t(i + 1) - t(i);
      return x(i - 1) * (-t2) / (t0 * (t0 - t2)) + x(i) * (-t0 - t2) / (t0 * t2) +
             x(i + 1) * (-t0) / (t2 * (t2 - t0));
    }
    if (next) return (x(i + 1) - x(i)) / (t(i + 1) - t(i));
    if (prev) return (x(i) - x(i - 1)) / (t(i) - t(i - 1));
    return 0.0;
  };
  for (size_t s = 0; s + 1 < n; ++s) {
    const size_t a = samples[s], b = samples[s + 1];
    const double h = static_cast<double>(b - a);
    for (size_t j = a; j < b; ++j) {
      const double u = static_cast<double>(j - a) / h, u2 = u * u, u3 = u2 * u;
      Pose shown = Lerp(truth[a], truth[b], u);
      auto herm = [&](float Vec3f::*c) {
        const bool long_gap = b - a > gap_limit;
        if (long_gap) return static_cast<double>(shown.p.*c);
        return (2 * u3 - 3 * u2 + 1) * (truth[a].p.*c) + (u3 - 2 * u2 + u) * h * tangent(s, c) +
               (-2 * u3 + 3 * u2) * (truth[b].p.*c) + (u3 - u2) * h * tangent(s + 1, c);
      };
      shown.p = {static_cast<float>(herm(&Vec3f::x)), static_cast<float>(herm(&Vec3f::y)),
                 static_cast<float>(herm(&Vec3f::z))};
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

// Key samples: the sample is the state now (tick b) when the curve the receiver would draw from
// the last sample a to b (Shown: the line, or a curve through the sample before a too) strays
// from a state in between, or after the max interval while the box moved.
std::vector<size_t> KeySamples(const std::vector<Pose>& truth, double threshold_m, size_t max_gap,
                               Curve curve = Curve::kLine, size_t gap_limit = 0,
                               double* strayed = nullptr) {
  std::vector<size_t> s = {0};
  const double rot_threshold = threshold_m * 10.0;  // 10 mm ~ 0.1 rad (5.7 deg)
  for (size_t b = 1; b < truth.size(); ++b) {
    const size_t a = s.back();
    const size_t prev = s.size() >= 2 ? s[s.size() - 2] : kNoPrev;
    bool stray = false;
    for (size_t j = a + 1; j < b && !stray; ++j) {
      const Pose shown = Shown(truth, prev, a, b, j, curve, gap_limit);
      stray = Dist(shown.p, truth[j].p) > threshold_m || AngleRad(shown.q, truth[j].q) > rot_threshold;
    }
    if (stray || (b - a >= max_gap && Moved(truth[a], truth[b]))) s.push_back(b);
    if (stray && strayed != nullptr) *strayed += 1;
  }
  if (s.back() != truth.size() - 1) s.push_back(truth.size() - 1);
  return s;
}

// Key samples where the relay picks, per sample, the line or the parabola (as if a bit in each
// record told the receiver which; the bit is not counted): a sample is due only when both stray
// (or at the max interval), and each segment is drawn with whichever strays least (in multiples
// of the thresholds) over its states. An upper bound for a per-record choice; `choice` gets each
// segment's curve.
double MaxExcess(const std::vector<Pose>& truth, size_t prev, size_t a, size_t b, Curve curve,
                 size_t gap_limit, double threshold_m, double rot_threshold) {
  double worst = 0;
  for (size_t j = a + 1; j < b; ++j) {
    const Pose shown = Shown(truth, prev, a, b, j, curve, gap_limit);
    worst = std::max(worst, std::max(Dist(shown.p, truth[j].p) / threshold_m,
                                     AngleRad(shown.q, truth[j].q) / rot_threshold));
  }
  return worst;
}
std::vector<size_t> BestOfSamples(const std::vector<Pose>& truth, double threshold_m, size_t max_gap,
                                  size_t gap_limit, std::vector<Curve>* choice, double* strayed) {
  std::vector<size_t> s = {0};
  choice->clear();
  const double rot_threshold = threshold_m * 10.0;
  auto pick = [&](size_t prev, size_t a, size_t b, double* excess) {
    const double line = MaxExcess(truth, prev, a, b, Curve::kLine, gap_limit, threshold_m, rot_threshold);
    const double quad = MaxExcess(truth, prev, a, b, Curve::kQuad, gap_limit, threshold_m, rot_threshold);
    *excess = std::min(line, quad);
    return quad < line ? Curve::kQuad : Curve::kLine;
  };
  for (size_t b = 1; b < truth.size(); ++b) {
    const size_t a = s.back();
    const size_t prev = s.size() >= 2 ? s[s.size() - 2] : kNoPrev;
    double excess = 0;
    const Curve c = pick(prev, a, b, &excess);
    const bool stray = excess > 1.0;
    if (stray || (b - a >= max_gap && Moved(truth[a], truth[b]))) {
      s.push_back(b);
      choice->push_back(c);
    }
    if (stray) *strayed += 1;
  }
  if (s.back() != truth.size() - 1) {
    double excess = 0;
    choice->push_back(pick(s.size() >= 2 ? s[s.size() - 2] : kNoPrev, s.back(), truth.size() - 1, &excess));
    s.push_back(truth.size() - 1);
  }
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
  const double curve_gap_limit = std::atof(Arg(argc, argv, "--curve-gap-limit", "1.0"));
  bool with_kink = false;
  for (int i = 1; i < argc; ++i) with_kink = with_kink || std::strcmp(argv[i], "--kink") == 0;
  if (p.num_objects <= 0 || seconds <= 0 || max_interval <= 0 || curve_gap_limit < 0) {
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
              "rotation_p99_deg,strayed_per_box_per_s\n");
  auto report = [&](const std::string& name, const Outcome& o) {
    const double per_box_s = o.samples / static_cast<double>(n) / seconds;
    const double mbit = per_box_s * static_cast<double>(n) * bytes_per_update * 8 / 1e6;
    std::printf("%s,%.3f,%.3f,%.2f,%.2f,%.2f,%.3f\n", name.c_str(), per_box_s, mbit / paper_mbit,
                Percentile(o.err_mm, 50), Percentile(o.err_mm, 99), Percentile(o.rot_deg, 99),
                o.strayed / static_cast<double>(n) / seconds);
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
  g_max_gap = max_gap;
  const size_t gap_limit = static_cast<size_t>(curve_gap_limit * 60.0 + 0.5);
  for (double mm : {5.0, 10.0, 15.0, 20.0, 30.0, 40.0}) {
    Outcome line, hermite;
    for (size_t k = 0; k < n; ++k) {
      const std::vector<size_t> s = KeySamples(truth[k], mm / 1000.0, max_gap, Curve::kLine, 0, &line.strayed);
      Score(truth[k], s, &line);
      ScoreHermite(truth[k], s, &hermite, gap_limit);
    }
    hermite.strayed = line.strayed;
    char name[96];
    std::snprintf(name, sizeof(name), "key samples %.0f mm", mm);
    report(name, line);
    std::snprintf(name, sizeof(name), "key samples %.0f mm shown as Hermite", mm);
    report(name, hermite);
  }
  const struct {
    Curve curve;
    const char* name;
  } curves[] = {{Curve::kQuad, "parabola"}, {Curve::kQuadRot, "parabola+rot"}, {Curve::kQuadHalf, "half parabola"},
                {Curve::kQuadSmooth, "parabola after an interval sample"}};
  for (const auto& c : curves) {
    for (double mm : {5.0, 10.0, 15.0, 20.0, 30.0, 40.0}) {
      Outcome o;
      for (size_t k = 0; k < n; ++k) {
        Score(truth[k], KeySamples(truth[k], mm / 1000.0, max_gap, c.curve, gap_limit, &o.strayed), &o,
              c.curve, gap_limit);
      }
      char name[96];
      std::snprintf(name, sizeof(name), "key samples on a %s %.0f mm", c.name, mm);
      report(name, o);
    }
  }
  for (double mm : {5.0, 10.0, 15.0, 20.0, 30.0, 40.0}) {
    Outcome o;
    std::vector<Curve> choice;
    for (size_t k = 0; k < n; ++k) {
      const std::vector<size_t> s = BestOfSamples(truth[k], mm / 1000.0, max_gap, gap_limit, &choice, &o.strayed);
      Score(truth[k], s, &o, Curve::kLine, gap_limit, &choice);
    }
    char name[96];
    std::snprintf(name, sizeof(name), "key samples on the line or a parabola %.0f mm", mm);
    report(name, o);
  }
  if (!with_kink) return 0;
  for (double mm : {10.0, 15.0, 20.0, 30.0, 40.0, 50.0}) {
    Outcome o;
    for (size_t k = 0; k < n; ++k) Score(truth[k], KinkSamples(truth[k], mm / 1000.0, max_gap, 30), &o);
    char name[64];
    std::snprintf(name, sizeof(name), "key samples at the kink %.0f mm", mm);
    report(name, o);
  }
  return 0;
}
