// escape_trace: where do boxes leave the full-stir container, and how? Steps the 2,000-box MultiObject scene
// (PhysSMultiObjectScene) with a candidate config for --seconds of simulated stirring and, for
// every box whose centre leaves the container (the report's rule: more than 5 cm past a wall's
// inner face, or 5 cm below the floor's top), prints one row: when, which box, through which wall,
// at what height, how fast, how far its centre moved in that step, how many steps it spent in the
// wall before, how far the stirrer's tip was, and a verdict:
//   flying  the centre crossed from clear of the wall (> one half extent inside) to outside
//           within 2 steps (a body too fast for its discrete contact);
//   pushed  the centre went through the wall slowly, over more steps (squeezed through by what
//           presses on it: the stirrer, directly or through other boxes);
//   over    the centre was above the wall's top (1.5 m) when it left: thrown out over the wall.
// Also prints the deepest wall penetration of any box centre over the run.
//
//   escape_trace [--objects 2000] [--seconds 60] [--only CANDIDATE] [--history 12]
//
// The last line is a contact census at the end of the run: broadphase pairs, those with a
// collision algorithm, those of two boxes, contact manifolds, and manifolds with at least one
// point.
//
// Not a timing: run it under the build lock like a test. Output CSV on stdout; per-escape step
// histories (depth past the wall's inner face, normal speed, stirrer tip distance) with
// --history N (the last N steps).
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <btBulletDynamicsCommon.h>

#include "bench/physics_cost_candidates.h"
#include "physics_backend/physics_world.h"
#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {
namespace {

struct Sample {
  Vec3f p{}, v{};
  float tip = 0;  // distance from the box centre to the nearer stirrer tip (m)
};

constexpr int kRing = 32;

const char* WallName(int w) {
  static const char* names[] = {"+x", "-x", "+z", "-z", "floor"};
  return names[w];
}

// Depth of the centre past each wall's inner face (m, positive: past it).
std::array<float, 5> Depths(const Vec3f& p, float w) {
  return {p.x - w, -p.x - w, p.z - w, -p.z - w, -p.y};
}

// Pairs, algorithms and manifolds at this moment. O(pairs + manifolds).
void PrintCensus(const std::string& only, PhysicsWorld& world) {
  btDiscreteDynamicsWorld* bw = world.BulletWorldForTesting();
  btOverlappingPairCache* cache = bw->getPairCache();
  const int pairs = cache->getNumOverlappingPairs();
  int with_algorithm = 0, box_box = 0;
  for (int i = 0; i < pairs; ++i) {
    const btBroadphasePair& pair = cache->getOverlappingPairArray()[i];
    if (pair.m_algorithm != nullptr) ++with_algorithm;
    const auto* o0 = static_cast<const btCollisionObject*>(pair.m_pProxy0->m_clientObject);
    const auto* o1 = static_cast<const btCollisionObject*>(pair.m_pProxy1->m_clientObject);
    if (o0->getCollisionShape()->getShapeType() == BOX_SHAPE_PROXYTYPE &&
        o1->getCollisionShape()->getShapeType() == BOX_SHAPE_PROXYTYPE) {
      ++box_box;
    }
  }
  btDispatcher* d = bw->getDispatcher();
  const int manifolds = d->getNumManifolds();
  int with_points = 0;
  for (int i = 0; i < manifolds; ++i) {
    if (d->getManifoldByIndexInternal(i)->getNumContacts() > 0) ++with_points;
  }
  std::printf("# census %s: broadphase pairs %d, with an algorithm %d, box-box %d; manifolds %d, "
              "with >= 1 point %d, empty %d (%.1f %%)\n",
              only.c_str(), pairs, with_algorithm, box_box, manifolds, with_points,
              manifolds - with_points,
              manifolds > 0 ? 100.0 * (manifolds - with_points) / manifolds : 0.0);
}

int Main(int argc, char** argv) {
  MultiObjectParams p;
  p.num_objects = 2000;
  double seconds = 60;
  int history = 0;
  std::string only = "new-defaults";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto next = [&]() -> std::string {
      if (i + 1 >= argc) std::exit(2);
      return argv[++i];
    };
    if (a == "--objects") p.num_objects = std::stoi(next());
    else if (a == "--seconds") seconds = std::stod(next());
    else if (a == "--only") only = next();
    else if (a == "--history") history = std::min(kRing, std::stoi(next()));
    else {
      std::fprintf(stderr,
                   "usage: escape_trace [--objects N] [--seconds S] [--only CANDIDATE] "
                   "[--history N]\n");
      return 2;
    }
  }
  bool found = false;
  for (const Candidate& c : Candidates()) {
    if (c.name == only) c.apply(p.config), found = true;
  }
  if (!found) {
    std::fprintf(stderr, "unknown candidate %s\n", only.c_str());
    return 2;
  }
  PhysSMultiObjectScene scene(p);
  PhysicsWorld& world = scene.world();
  const float w = MultiObjectHalfWidth(p);
  const float he = p.box_half_extent;
  const float lim = 0.05f;  // the report's Escaped() rule
  const int n = p.num_objects;
  const int steps = static_cast<int>(seconds / p.config.fixed_dt + 0.5);
  std::vector<std::array<Sample, kRing>> ring(static_cast<size_t>(n));
  std::vector<bool> out(static_cast<size_t>(n), false);
  std::vector<int> in_wall_since(static_cast<size_t>(n), -1);  // step the centre passed a face
  std::vector<bool> above(static_cast<size_t>(n), false);  // ever above the walls' top
  size_t launched = 0;  // counted after the spawned layers have fallen in (5 s)
  const int settle = static_cast<int>(5.0 / p.config.fixed_dt);
  float highest = 0;
  float deepest = 0;
  int deepest_step = 0;
  uint32_t deepest_id = 0;
  size_t escapes = 0;
  std::printf("candidate,step,time_s,box,wall,y,depth_m,step_move_m,speed_before,"
              "normal_speed_max_8,steps_in_wall,tip_m,verdict\n");
  for (int s = 1; s <= steps; ++s) {
    scene.Step();
    Vec3f sp;
    Quatf sr;
    StirrerPose(p, s * static_cast<double>(p.config.fixed_dt), &sp, &sr);
    // Stirrer tips: the paddle's local x axis rotated by sr (about +Y).
    const float yaw = 2.0f * std::atan2(sr.y, sr.w);
    const float reach = p.stirrer_reach * w;
    const float tx = reach * std::cos(yaw), tz = -reach * std::sin(yaw);
    for (int i = 0; i < n; ++i) {
      const uint32_t id = kSceneFirstBoxId + static_cast<uint32_t>(i);
      EntityState st;
      Vec3f v, av;
      (void)world.GetState(id, &st);
      (void)world.GetVelocity(id, &v, &av);
      Sample& cur = ring[i][s % kRing];
      cur.p = st.position;
      cur.v = v;
      const float d1 = std::hypot(cur.p.x - tx, cur.p.z - tz);
      const float d2 = std::hypot(cur.p.x + tx, cur.p.z + tz);
      cur.tip = std::min(d1, d2);
      const std::array<float, 5> dep = Depths(cur.p, w);
      int wall = 0;
      for (int k = 1; k < 5; ++k) {
        if (dep[k] > dep[wall]) wall = k;
      }
      const float depth = dep[wall];
      const bool below_top = cur.p.y < p.wall_height;
      highest = std::max(highest, cur.p.y);
      if (!below_top && !above[i] && s > settle) above[i] = true, ++launched;
      if (below_top && depth > deepest && !out[i]) {
        deepest = depth, deepest_step = s, deepest_id = id;
      }
      if (depth > 0 && in_wall_since[i] < 0) in_wall_since[i] = s;
      if (depth <= 0) in_wall_since[i] = -1;
      if (out[i] || depth <= lim) continue;
      out[i] = true;
      ++escapes;
      const Sample& prev = ring[i][(s - 1 + kRing) % kRing];
      const Sample& prev2 = ring[i][(s - 2 + kRing) % kRing];
      const float move = std::sqrt((cur.p.x - prev.p.x) * (cur.p.x - prev.p.x) +
                                   (cur.p.y - prev.p.y) * (cur.p.y - prev.p.y) +
                                   (cur.p.z - prev.p.z) * (cur.p.z - prev.p.z));
      const float speed = std::sqrt(prev.v.x * prev.v.x + prev.v.y * prev.v.y +
                                    prev.v.z * prev.v.z);
      float vn_max = 0;
      for (int b = 0; b < 8 && b < s; ++b) {
        const Sample& q = ring[i][(s - b + kRing) % kRing];
        const float vn[5] = {q.v.x, -q.v.x, q.v.z, -q.v.z, -q.v.y};
        vn_max = std::max(vn_max, vn[wall]);
      }
      const bool flying = s >= 2 && Depths(prev2.p, w)[wall] < -he;
      const bool over = wall != 4 && cur.p.y > p.wall_height;
      std::printf("%s,%d,%.3f,%u,%s,%.3f,%.3f,%.3f,%.2f,%.2f,%d,%.3f,%s\n", only.c_str(), s,
                  s * p.config.fixed_dt, id, WallName(wall), cur.p.y, depth, move, speed, vn_max,
                  in_wall_since[i] >= 0 ? s - in_wall_since[i] : 0, cur.tip,
                  over ? "over" : flying ? "flying" : "pushed");
      for (int b = std::min(history, s) - 1; b >= 0; --b) {
        const Sample& q = ring[i][(s - b + kRing) % kRing];
        const float vn[5] = {q.v.x, -q.v.x, q.v.z, -q.v.z, -q.v.y};
        std::printf("#   step %d depth %.3f normal_speed %.2f y %.3f tip %.3f\n", s - b,
                    Depths(q.p, w)[wall], vn[wall], q.p.y, q.tip);
      }
      std::fflush(stdout);
    }
  }
  std::printf("# %s: %zu escaped in %.0f s (%d steps); deepest centre past a wall's inner face "
              "while inside: %.3f m (box %u, step %d); box half extent %.2f m, wall half "
              "thickness 0.10 m; %zu boxes were thrown above the walls' top after "
              "5 s (highest centre %.2f m)\n",
              only.c_str(), escapes, seconds, steps, deepest, deepest_id, deepest_step, he,
              launched, highest);
  PrintCensus(only, world);
  return 0;
}

}  // namespace
}  // namespace edgephys::physics

int main(int argc, char** argv) { return edgephys::physics::Main(argc, argv); }
