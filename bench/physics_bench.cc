// PhyS step time: the MultiObject scene (N boxes stirred in a walled container, scenes.h) stepped
// by PhysicsWorld at PhyS's defaults (plus CollectStates/DrainEvents, as the relay calls them)
// and by raw Bullet with Bullet's default settings on the same scene, as a ratio of medians
// taken in the same run; and PhysicsWorld at 1,000 boxes over solver iterations x substeps (the
// cost side of the accuracy table printed by physics_accuracy_test, StepTimeVsAccuracyTable).
// Per-setting step time against accuracy: bench/physics_cost_report.cc.
//
// Both variants of one size run the same fixed number of steps after the same warm-up, i.e. the
// same simulated interval (the scene is deterministic), so their medians compare like for like.
// Ratio at 2,000 boxes (issue 15's target: at most 0.5):
//   build/physbench/bench/physics_bench --benchmark_repetitions=5
//     --benchmark_report_aggregates_only=true --benchmark_filter='MultiObject'
//   (one line), then divide the PhysS median by the RawBullet median of the same size.
#include <benchmark/benchmark.h>

#include <memory>

#include "loadgen/scenes/scenes.h"

namespace edgephys::physics {
namespace {

constexpr int kWarmupSteps = 60;    // 1 s: boxes have landed, the stirrer is moving
constexpr int kMeasuredSteps = 90;  // benchmark iterations per repetition

MultiObjectParams Params(int n, int iterations = PhysicsConfig{}.solver_iterations,
                         int substeps = 1) {
  MultiObjectParams p;
  p.num_objects = n;
  p.config.solver_iterations = iterations;
  p.config.substeps = substeps;
  return p;
}

template <typename Scene>
void RunScene(benchmark::State& state, const MultiObjectParams& p) {
  auto scene = std::make_unique<Scene>(p);
  for (int i = 0; i < kWarmupSteps; ++i) scene->Step();
  for (auto _ : state) scene->Step();
  state.counters["boxes"] = static_cast<double>(p.num_objects);
  state.counters["moving"] = static_cast<double>(scene->MovingBoxes(0.05f));
  state.SetItemsProcessed(state.iterations() * p.num_objects);  // box-steps per second
}

void BM_MultiObject_PhysS(benchmark::State& state) {
  RunScene<PhysSMultiObjectScene>(state, Params(static_cast<int>(state.range(0))));
}

void BM_MultiObject_RawBullet(benchmark::State& state) {
  RunScene<RawBulletMultiObjectScene>(state, Params(static_cast<int>(state.range(0))));
}

// Interleaved registration: PhysS and raw Bullet of one size run back to back.
BENCHMARK(BM_MultiObject_PhysS)->Arg(500)->Iterations(kMeasuredSteps)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MultiObject_RawBullet)->Arg(500)->Iterations(kMeasuredSteps)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MultiObject_PhysS)->Arg(1000)->Iterations(kMeasuredSteps)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MultiObject_RawBullet)->Arg(1000)->Iterations(kMeasuredSteps)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MultiObject_PhysS)->Arg(2000)->Iterations(kMeasuredSteps)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MultiObject_RawBullet)->Arg(2000)->Iterations(kMeasuredSteps)->Unit(benchmark::kMillisecond);

// Step time against solver iterations x substeps (PhysicsWorld, 1,000 boxes).
void BM_IterationsSubsteps_PhysS(benchmark::State& state) {
  RunScene<PhysSMultiObjectScene>(
      state, Params(1000, static_cast<int>(state.range(0)), static_cast<int>(state.range(1))));
}
BENCHMARK(BM_IterationsSubsteps_PhysS)
    ->ArgNames({"iterations", "substeps"})
    ->ArgsProduct({{4, 10, 20}, {1, 2, 4}})
    ->Iterations(kMeasuredSteps)
    ->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace edgephys::physics

BENCHMARK_MAIN();
