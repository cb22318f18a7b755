// A sizing spike for issue 15's Done-when line 1:
// on the same poses and the same broadphase pairs of the 2,000-box full stir stepped by PhyS at
// its defaults, what does the box-box narrowphase cost
//   * through Bullet's dispatcher (collision objects, algorithms, 880-byte manifolds: what a PhyS
//     step pays today),
//   * as Bullet's box-box detector alone on the same pairs (the test without the manifolds), and
//   * from compact arrays (a 64-byte box record, an 8-byte pair, 32-byte contacts) with a
//     box-box contact generator written here (separating axes, then the incident face clipped
//     against the reference face, or one point for an edge pair)?
// Every variant runs after the caches have been flushed (a real step walks the solver's rows
// between two narrowphases), in thread CPU time, median of --reps. The compact generator is
// checked against Bullet's detector pair by pair (touching or not, deepest penetration, number
// of points); the run fails (exit 1) if they disagree beyond the printed bounds, so a faster
// but wrong generator cannot report a figure.
//
// Not a product path: nothing in PhyS uses this generator. It sizes the change that line 1
// needs; a solver over compact rows is not modelled.
//
//   compact_narrowphase_report [--objects N] [--warmup STEPS] [--reps R]
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>
#include <unordered_map>
#include <vector>

#include <BulletCollision/CollisionDispatch/btBoxBoxDetector.h>
#include <btBulletDynamicsCommon.h>

#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {
namespace {

double ThreadCpuMs() {
  timespec ts{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

double Median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[v.size() / 2];
}

// Evicts the caches (64 MB written and read) so that every variant starts cold, as in a step.
void FlushCaches() {
  static std::vector<unsigned char> junk(64u << 20);
  static unsigned sink = 0;
  for (size_t i = 0; i < junk.size(); i += 64) junk[i] = static_cast<unsigned char>(junk[i] + 1);
  for (size_t i = 0; i < junk.size(); i += 64) sink += junk[i];
  if (sink == 1) std::printf(" ");
}

struct V3 {
  float x, y, z;
};
inline V3 operator+(V3 a, V3 b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
inline V3 operator-(V3 a, V3 b) { return {a.x - b.x, a.y - b.y, a.z - b.z}; }
inline V3 operator*(V3 a, float s) { return {a.x * s, a.y * s, a.z * s}; }
inline float Dot(V3 a, V3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
inline V3 Cross(V3 a, V3 b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }

struct alignas(64) Box {  // 64 bytes: centre, the three unit axes, half extents
  V3 c;
  V3 ax[3];
  float h[3];
};
struct Pair {
  uint32_t a, b;
};
struct Contact {  // 32 bytes
  V3 point;       // on the incident face (face pairs) or midway (edge pairs), world
  V3 normal;      // from box a towards box b
  float depth;    // penetration, m (> 0 inside)
  uint32_t pair;
};

// Clips polygon `in` (n points) to the half space dot(p, axis) <= limit. Returns the count.
int ClipPlane(const V3* in, int n, V3 axis, float limit, V3* out) {
  int m = 0;
  for (int i = 0; i < n; ++i) {
    const V3 p = in[i], q = in[(i + 1) % n];
    const float dp = Dot(p, axis) - limit, dq = Dot(q, axis) - limit;
    if (dp <= 0) out[m++] = p;
    if ((dp < 0) != (dq < 0) && dp != dq) out[m++] = p + (q - p) * (dp / (dp - dq));
  }
  return m;
}

// Up to 4 of `n` contacts: the deepest, the farthest from it, then the two that span the largest
// areas on either side of that line.
int ReduceToFour(Contact* c, int n) {
  if (n <= 4) return n;
  int i0 = 0;
  for (int i = 1; i < n; ++i) if (c[i].depth > c[i0].depth) i0 = i;
  int i1 = i0 == 0 ? 1 : 0;
  float best = -1;
  for (int i = 0; i < n; ++i) {
    const V3 d = c[i].point - c[i0].point;
    if (i != i0 && Dot(d, d) > best) best = Dot(d, d), i1 = i;
  }
  const V3 e = c[i1].point - c[i0].point;
  int i2 = -1, i3 = -1;
  float hi = 0, lo = 0;
  for (int i = 0; i < n; ++i) {
    if (i == i0 || i == i1) continue;
    const float a = Dot(Cross(e, c[i].point - c[i0].point), c[i0].normal);
    if (a > hi) hi = a, i2 = i;
    if (a < lo) lo = a, i3 = i;
  }
  Contact keep[4];
  int m = 0;
  for (int i : {i0, i1, i2, i3}) if (i >= 0) keep[m++] = c[i];
  std::copy(keep, keep + m, c);
  return m;
}

// Contacts of boxes `A` and `B` (at most 4 into `out`), 0 if they are apart.
int BoxBox(const Box& A, const Box& B, uint32_t pair_index, Contact* out) {
  const V3 d = B.c - A.c;
  float C[3][3], absC[3][3];
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) C[i][j] = Dot(A.ax[i], B.ax[j]), absC[i][j] = std::fabs(C[i][j]) + 1e-6f;
  float best = -1e30f;
  int kind = -1, index = 0;  // 0: face of A, 1: face of B, 2: edge pair (index = i*3+j)
  V3 axis{};
  for (int i = 0; i < 3; ++i) {
    const float s = std::fabs(Dot(d, A.ax[i])) - (A.h[i] + B.h[0] * absC[i][0] + B.h[1] * absC[i][1] + B.h[2] * absC[i][2]);
    if (s > 0) return 0;
    if (s > best) best = s, kind = 0, index = i, axis = A.ax[i];
  }
  for (int j = 0; j < 3; ++j) {
    const float s = std::fabs(Dot(d, B.ax[j])) - (A.h[0] * absC[0][j] + A.h[1] * absC[1][j] + A.h[2] * absC[2][j] + B.h[j]);
    if (s > 0) return 0;
    if (s > best) best = s, kind = 1, index = j, axis = B.ax[j];
  }
  const float face_best = best;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      V3 l = Cross(A.ax[i], B.ax[j]);
      const float len = std::sqrt(Dot(l, l));
      if (len < 1e-4f) continue;  // parallel edges: a face axis decides
      l = l * (1.0f / len);
      const float ra = A.h[0] * std::fabs(Dot(A.ax[0], l)) + A.h[1] * std::fabs(Dot(A.ax[1], l)) + A.h[2] * std::fabs(Dot(A.ax[2], l));
      const float rb = B.h[0] * std::fabs(Dot(B.ax[0], l)) + B.h[1] * std::fabs(Dot(B.ax[1], l)) + B.h[2] * std::fabs(Dot(B.ax[2], l));
      const float s = std::fabs(Dot(d, l)) - ra - rb;
      if (s > 0) return 0;
      // An edge axis wins only clearly over the faces (stable face contacts in piles).
      if (s > best && s > 0.95f * face_best + 1e-4f) best = s, kind = 2, index = i * 3 + j, axis = l;
    }
  }
  const V3 n = Dot(d, axis) < 0 ? axis * -1.0f : axis;  // from A towards B
  if (kind == 2) {
    const int i = index / 3, j = index % 3;
    V3 ea = A.c, eb = B.c;
    for (int k = 0; k < 3; ++k) {
      if (k != i) ea = ea + A.ax[k] * (Dot(A.ax[k], n) > 0 ? A.h[k] : -A.h[k]);
      if (k != j) eb = eb + B.ax[k] * (Dot(B.ax[k], n) < 0 ? B.h[k] : -B.h[k]);
    }
    const V3 r = ea - eb;
    const float b = Dot(A.ax[i], B.ax[j]), c = Dot(A.ax[i], r), f = Dot(B.ax[j], r);
    const float denom = std::max(1.0f - b * b, 1e-6f);
    const float s = std::clamp((b * f - c) / denom, -A.h[i], A.h[i]);
    const float t = std::clamp(f + s * b, -B.h[j], B.h[j]);
    const V3 pa = ea + A.ax[i] * s, pb = eb + B.ax[j] * t;
    out[0] = {(pa + pb) * 0.5f, n, -best, pair_index};
    return 1;
  }
  // Face contact: reference face on `ref` (normal nr towards the other box), incident face on `inc`.
  const Box& ref = kind == 0 ? A : B;
  const Box& inc = kind == 0 ? B : A;
  const V3 nr = kind == 0 ? n : n * -1.0f;
  const int u = (index + 1) % 3, v = (index + 2) % 3;
  const V3 fc = ref.c + nr * ref.h[index];
  int k = 0;
  float most = -1;
  for (int m = 0; m < 3; ++m) {
    const float a = std::fabs(Dot(inc.ax[m], nr));
    if (a > most) most = a, k = m;
  }
  const V3 ic = inc.c + inc.ax[k] * (Dot(inc.ax[k], nr) > 0 ? -inc.h[k] : inc.h[k]);
  const V3 a1 = inc.ax[(k + 1) % 3] * inc.h[(k + 1) % 3], a2 = inc.ax[(k + 2) % 3] * inc.h[(k + 2) % 3];
  V3 poly[8] = {ic + a1 + a2, ic - a1 + a2, ic - a1 - a2, ic + a1 - a2};
  V3 tmp[8];
  int count = 4;
  const float cu = Dot(fc, ref.ax[u]), cv = Dot(fc, ref.ax[v]);
  count = ClipPlane(poly, count, ref.ax[u], cu + ref.h[u], tmp);
  count = ClipPlane(tmp, count, ref.ax[u] * -1.0f, -cu + ref.h[u], poly);
  count = ClipPlane(poly, count, ref.ax[v], cv + ref.h[v], tmp);
  count = ClipPlane(tmp, count, ref.ax[v] * -1.0f, -cv + ref.h[v], poly);
  Contact found[8];
  int m = 0;
  for (int q = 0; q < count; ++q) {
    const float depth = -Dot(poly[q] - fc, nr);
    if (depth >= 0) found[m++] = {poly[q], n, depth, pair_index};
  }
  m = ReduceToFour(found, m);
  std::copy(found, found + m, out);
  return m;
}

// Bullet's detector's points for one pair (its depth is a signed distance: < 0 inside).
struct Collector : btDiscreteCollisionDetectorInterface::Result {
  int count = 0;
  float deepest = 0;
  void setShapeIdentifiersA(int, int) override {}
  void setShapeIdentifiersB(int, int) override {}
  void addContactPoint(const btVector3&, const btVector3&, btScalar depth) override {
    ++count;
    deepest = std::max(deepest, static_cast<float>(-depth));
  }
};

Box FromBullet(const btCollisionObject* o) {
  const auto* shape = static_cast<const btBoxShape*>(o->getCollisionShape());
  const btTransform& t = o->getWorldTransform();
  const btVector3 h = shape->getHalfExtentsWithMargin();
  Box b{};
  b.c = {static_cast<float>(t.getOrigin().x()), static_cast<float>(t.getOrigin().y()), static_cast<float>(t.getOrigin().z())};
  for (int i = 0; i < 3; ++i) {
    const btVector3 col = t.getBasis().getColumn(i);
    b.ax[i] = {static_cast<float>(col.x()), static_cast<float>(col.y()), static_cast<float>(col.z())};
    b.h[i] = static_cast<float>(h[i]);
  }
  return b;
}

int Main(int argc, char** argv) {
  MultiObjectParams p;
  p.num_objects = 2000;
  int warmup = 600, reps = 31;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 >= argc) {
      std::fprintf(stderr, "usage: compact_narrowphase_report [--objects N] [--warmup STEPS] [--reps R]\n");
      return 2;
    }
    if (a == "--objects") p.num_objects = std::atoi(argv[++i]);
    else if (a == "--warmup") warmup = std::atoi(argv[++i]);
    else if (a == "--reps") reps = std::max(3, std::atoi(argv[++i]));
    else {
      std::fprintf(stderr, "unknown option %s\n", a.c_str());
      return 2;
    }
  }
  PhysSMultiObjectScene scene(p);
  for (int s = 0; s < warmup; ++s) scene.Step();
  btDiscreteDynamicsWorld* bw = scene.world().BulletWorldForTesting();
  btOverlappingPairCache* cache = bw->getPairCache();
  btDispatcher* dispatcher = bw->getDispatcher();

  // The scene's box-box pairs, in the cache's order, and the compact copy of every box in one.
  std::vector<const btCollisionObject*> objects;
  std::vector<std::pair<const btCollisionObject*, const btCollisionObject*>> bt_pairs;
  std::vector<Pair> pairs;
  std::vector<Box> boxes;
  std::unordered_map<const btCollisionObject*, uint32_t> slots;
  auto slot = [&](const btCollisionObject* o) -> uint32_t {
    auto [it, added] = slots.emplace(o, static_cast<uint32_t>(objects.size()));
    if (added) objects.push_back(o);
    return it->second;
  };
  for (int i = 0; i < cache->getNumOverlappingPairs(); ++i) {
    const btBroadphasePair& bp = cache->getOverlappingPairArray()[i];
    const auto* o0 = static_cast<const btCollisionObject*>(bp.m_pProxy0->m_clientObject);
    const auto* o1 = static_cast<const btCollisionObject*>(bp.m_pProxy1->m_clientObject);
    if (o0->getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE ||
        o1->getCollisionShape()->getShapeType() != BOX_SHAPE_PROXYTYPE) {
      continue;
    }
    bt_pairs.emplace_back(o0, o1);
    pairs.push_back({slot(o0), slot(o1)});
  }
  boxes.resize(objects.size());
  for (size_t i = 0; i < objects.size(); ++i) boxes[i] = FromBullet(objects[i]);

  // Check: the compact generator against Bullet's detector, pair by pair.
  std::vector<Contact> contacts(pairs.size() * 4);
  size_t agree = 0, both = 0, bt_only = 0, compact_only = 0, count_equal = 0;
  float worst_depth = 0, worst_missed = 0;
  std::vector<float> depth_diffs;
  float worst_bt = 0, worst_mine = 0;
  size_t depth_outliers = 0;  // pairs whose deepest points differ by more than 5 % + 0.1 mm
  for (size_t i = 0; i < pairs.size(); ++i) {
    const auto* s0 = static_cast<const btBoxShape*>(bt_pairs[i].first->getCollisionShape());
    const auto* s1 = static_cast<const btBoxShape*>(bt_pairs[i].second->getCollisionShape());
    btBoxBoxDetector detector(s0, s1);
    btDiscreteCollisionDetectorInterface::ClosestPointInput in;
    in.m_transformA = bt_pairs[i].first->getWorldTransform();
    in.m_transformB = bt_pairs[i].second->getWorldTransform();
    Collector bt;
    detector.getClosestPoints(in, bt, nullptr);
    Contact c[4];
    const int m = BoxBox(boxes[pairs[i].a], boxes[pairs[i].b], static_cast<uint32_t>(i), c);
    float deepest = 0;
    for (int q = 0; q < m; ++q) deepest = std::max(deepest, c[q].depth);
    if ((bt.count > 0) == (m > 0)) ++agree;
    if (bt.count > 0 && m > 0) {
      ++both;
      const float diff = std::fabs(deepest - bt.deepest);
      depth_diffs.push_back(diff);
      if (diff > worst_depth) worst_depth = diff, worst_bt = bt.deepest, worst_mine = deepest;
      if (diff > 0.05f * std::max(deepest, bt.deepest) + 1e-4f) ++depth_outliers;
      if (bt.count == m) ++count_equal;
    } else if (bt.count > 0) {
      ++bt_only;
      worst_missed = std::max(worst_missed, bt.deepest);
    } else if (m > 0) {
      ++compact_only;
      worst_missed = std::max(worst_missed, deepest);
    }
  }
  std::printf("# %d boxes after %d steps of the full stir (PhyS defaults): %zu box-box pairs, %zu objects\n",
              p.num_objects, warmup, pairs.size(), objects.size());
  std::printf("# check against btBoxBoxDetector: touching agrees on %zu of %zu pairs (both %zu, Bullet only %zu, "
              "compact only %zu; deepest of those %.3f mm); deepest penetration differs by at most %.3f mm; "
              "same point count on %zu of %zu\n",
              agree, pairs.size(), both, bt_only, compact_only, worst_missed * 1e3, worst_depth * 1e3,
              count_equal, both);
  std::sort(depth_diffs.begin(), depth_diffs.end());
  const float p99_diff = depth_diffs.empty() ? 0 : depth_diffs[depth_diffs.size() * 99 / 100];
  std::printf("# deepest penetration: p99 difference %.4f mm; the worst pair %.3f mm (Bullet) against %.3f mm; "
              "%zu pairs differ by more than 5 %% + 0.1 mm\n",
              p99_diff * 1e3, worst_bt * 1e3, worst_mine * 1e3, depth_outliers);

  std::vector<double> dispatch_ms, detector_ms, compact_ms, gather_ms;
  size_t sink = 0;
  for (int r = 0; r < reps; ++r) {
    FlushCaches();
    double t0 = ThreadCpuMs();
    dispatcher->dispatchAllCollisionPairs(cache, bw->getDispatchInfo(), dispatcher);
    dispatch_ms.push_back(ThreadCpuMs() - t0);

    FlushCaches();
    t0 = ThreadCpuMs();
    for (const auto& [o0, o1] : bt_pairs) {
      btBoxBoxDetector detector(static_cast<const btBoxShape*>(o0->getCollisionShape()),
                                static_cast<const btBoxShape*>(o1->getCollisionShape()));
      btDiscreteCollisionDetectorInterface::ClosestPointInput in;
      in.m_transformA = o0->getWorldTransform();
      in.m_transformB = o1->getWorldTransform();
      Collector bt;
      detector.getClosestPoints(in, bt, nullptr);
      sink += static_cast<size_t>(bt.count);
    }
    detector_ms.push_back(ThreadCpuMs() - t0);

    FlushCaches();
    t0 = ThreadCpuMs();
    for (size_t i = 0; i < objects.size(); ++i) boxes[i] = FromBullet(objects[i]);
    gather_ms.push_back(ThreadCpuMs() - t0);

    FlushCaches();
    t0 = ThreadCpuMs();
    size_t n = 0;
    for (size_t i = 0; i < pairs.size(); ++i) {
      n += static_cast<size_t>(BoxBox(boxes[pairs[i].a], boxes[pairs[i].b], static_cast<uint32_t>(i), &contacts[n]));
    }
    compact_ms.push_back(ThreadCpuMs() - t0);
    sink += n;
  }
  const double dispatch = Median(dispatch_ms), detector = Median(detector_ms);
  const double compact = Median(compact_ms), gather = Median(gather_ms);
  std::printf("variant,cpu_ms_median,ratio_to_dispatcher\n");
  std::printf("bullet_dispatcher,%.3f,1.000\n", dispatch);
  std::printf("bullet_detector_only,%.3f,%.3f\n", detector, detector / dispatch);
  std::printf("compact,%.3f,%.3f\n", compact, compact / dispatch);
  std::printf("compact_plus_gather,%.3f,%.3f\n", compact + gather, (compact + gather) / dispatch);
  std::printf("# medians of %d cold runs each; sink %zu\n", reps, sink);
  // The bounds: a generator that misses or invents contacts, or gets depths wrong, reports nothing.
  const bool ok = agree >= pairs.size() - pairs.size() / 200 && worst_missed < 1e-3f &&
                  p99_diff < 1e-4f && depth_outliers <= both / 200 && count_equal >= both * 9 / 10;
  if (!ok) std::printf("# FAILED: the compact generator disagrees with Bullet's detector beyond the bounds\n");
  return ok ? 0 : 1;
}

}  // namespace
}  // namespace edgephys::physics

int main(int argc, char** argv) { return edgephys::physics::Main(argc, argv); }
