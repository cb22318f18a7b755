#!/usr/bin/env bash
# Reruns every figures-page scenario and rewrites docs/benchmarks.md's tables and charts.
#
#   scripts/bench.sh                  full mode: every scenario at the page's sizes (about 28 min
#                                     on 2 cores), rewrites docs/benchmarks.md, docs/charts/
#                                     figures.json and the charts in docs/charts/
#   scripts/bench.sh --short --out D  short mode (under 3 minutes on 2 cores): small sizes and
#                                     durations; writes D/benchmarks.md, D/figures.json, D/raw/
#                                     and the charts into D, never into docs/; then checks that
#                                     every table it measured has rows with numbers
# Options:
#   --build DIR     build tree holding loadgen/edgephys-loadgen (default build/release, the
#                   `release` preset; the full mode also runs its bench/codec_bench when present)
#   --loadgen PATH  the edgephys-loadgen binary (overrides --build's)
#   --out DIR       where the page, the figures JSON, raw/ and the charts go
#   --only LIST     run only these scenarios (comma separated: relay_compare, interp_sweep,
#                   codec_sweep, multiobject_quarter, multiobject_full, softbody, ccu, ceiling,
#                   messages, codec_bench); the page keeps the others' committed tables
#
# Needs python3 and gnuplot; `ceiling` needs iperf3 (scripts/setup.sh installs all three).
# Exit status: 0 done, 1 a scenario or the check failed, 2 bad usage.
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
short=0
build="$root/build/release"
loadgen=""
out=""
only=""
while [ $# -gt 0 ]; do
  case "$1" in
    --short) short=1 ;;
    --build) build="$2"; shift ;;
    --loadgen) loadgen="$2"; shift ;;
    --out) out="$2"; shift ;;
    --only) only="$2"; shift ;;
    -h|--help) sed -n '2,20p' "$0"; exit 0 ;;
    *) echo "bench.sh: unknown argument $1" >&2; exit 2 ;;
  esac
  shift
done
[ -n "$loadgen" ] || loadgen="$build/loadgen/edgephys-loadgen"
if [ ! -x "$loadgen" ]; then
  echo "bench.sh: no edgephys-loadgen at $loadgen (build it: cmake --preset release &&" \
       "cmake --build build/release --target edgephys-loadgen codec_bench physics_accuracy_report)" >&2
  exit 2
fi
if [ "$short" = 1 ] && [ -z "$out" ]; then
  echo "bench.sh: --short writes into --out DIR only (it never rewrites docs/)" >&2
  exit 2
fi
for tool in python3 gnuplot; do
  command -v "$tool" >/dev/null || { echo "bench.sh: $tool is not installed" >&2; exit 2; }
done

figures="$root/scripts/bench/figures.py"
committed="$root/docs/charts/figures.json"
if [ -z "$out" ]; then
  out="$root/docs/charts"
  doc="$root/docs/benchmarks.md"
else
  mkdir -p "$out"
  out="$(cd "$out" && pwd)"
  doc="$out/benchmarks.md"
  cp "$root/docs/benchmarks.md" "$doc"
fi
raw="$out/raw"
mkdir -p "$raw"
rm -f "$raw"/*.json

failed=0
wanted() {  # NAME: whether --only (if given) lists NAME's scenario (NAME up to its first dot)
  [ -z "$only" ] || [[ ",$only," == *",${1%%.*},"* ]]
}
run() {  # NAME ARGS...: one scenario into raw/NAME.json, its table on stdout
  local name="$1"; shift
  wanted "$name" || return 0
  echo "== $name: edgephys-loadgen $*"
  local quiet=()  # offline scenarios have no progress line
  if "$loadgen" "$1" --help 2>/dev/null | grep -q -- --no-progress; then quiet=(--no-progress); fi
  if ! "$loadgen" "$@" --json "$raw/$name.json" "${quiet[@]}"; then
    echo "bench.sh: $name failed" >&2
    failed=1
    rm -f "$raw/$name.json"
  fi
}
run_charts() {  # the same for scenarios with --charts (the page draws its own charts)
  local name="$1"; shift
  run "$name" "$@" --charts ''
}

start=$(date +%s)
cd "$out"
if [ "$short" = 1 ]; then
  run_charts relay_compare relay-compare --objects 32,128 --modes photon,paper,edgephys \
    --duration 2 --warmup 0.5 --receivers 2
  run_charts interp_sweep interp-sweep --rates 12,30,60 --interpolators lerp-slerp,hermite,none \
    --duration 3 --objects 4
  run_charts codec_sweep codec-sweep --steps 0.001,0.002 --rotation-bounds 0.1 --thresholds 0.0005 \
    --objects 32 --duration 3
  run_charts multiobject_quarter multiobject --objects 200 --layers 1 --stirrer-reach 0.75 \
    --stirrer-speed 1.0 --duration 2 --settle-steps 30 --bench-warmup 10 --bench-steps 30 \
    --bench-max 3 --bench-min-steps 10
  run_charts multiobject_full multiobject --objects 300 --duration 2 --settle-steps 30 \
    --bench-warmup 10 --bench-steps 30 --bench-max 3 --bench-min-steps 10
  run_charts softbody softbody --bunnies 1 --duration 2 --settle-steps 30 --bench-warmup 10 \
    --bench-steps 30
  run_charts ccu ccu --users 20 --rooms 2 --ramp 2 --duration 4
  run ceiling ceiling --io-threads 1 --clients 32 --rooms 4 --warmup 0.5 --duration 1 \
    --iperf-seconds 1 --repeat 1
  run messages.1 messages --users 25 --rate 40 --warmup 0.3 --duration 1 --property-seconds 0.5
  run messages.2 messages --users 25 --rate 40 --unreliable --warmup 0.3 --duration 1 \
    --property-seconds 0.5
else
  run_charts relay_compare relay-compare --objects 32,64,128,256,512 \
    --modes photon,paper,edgephys --duration 10 --receivers 2
  run_charts interp_sweep interp-sweep --rates 6,12,24,30,48,60 \
    --interpolators lerp-slerp,hermite,none --duration 20 --seed 1 --objects 16
  run_charts codec_sweep codec-sweep --steps 0.0005,0.001,0.002,0.005 \
    --rotation-bounds 0.05,0.1,0.2,0.5 --thresholds 0,0.0005,0.001,0.005 --objects 128 \
    --rate 12 --duration 10
  run_charts multiobject_quarter multiobject --objects 1000 --layers 1 --stirrer-reach 0.75 \
    --stirrer-speed 1.0 --duration 8
  run_charts multiobject_full multiobject --objects 500,1000,2000 --duration 8
  run_charts softbody softbody --bunnies 1,3
  for i in 1 2 3; do  # medians of 3; each configuration clean and with a tenth of the users lossy
    run_charts ccu.$i.1 ccu --users 100 --rooms 1 --ramp 10 --duration 20
    run_charts ccu.$i.2 ccu --users 100 --rooms 1 --ramp 10 --duration 20 --impaired 0.1
    run_charts ccu.$i.3 ccu --users 250 --rooms 10 --ramp 8 --duration 15
    run_charts ccu.$i.4 ccu --users 250 --rooms 10 --ramp 8 --duration 15 --impaired 0.1
    run_charts ccu.$i.5 ccu --users 250 --rooms 1 --ramp 8 --duration 12
    run_charts ccu.$i.6 ccu --users 1000 --rooms 40 --ramp 20 --duration 15
  done
  run ceiling ceiling --io-threads 1,2 --repeat 3
  for i in 1 2 3; do  # medians of 3 (figures.py takes them)
    run messages.$i messages --users 25 --rate 200
    run messages.$((i + 3)) messages --users 25 --rate 200 --unreliable
  done
  if [ -x "$build/bench/codec_bench" ] && wanted codec_bench; then
    echo "== codec_bench"
    "$build/bench/codec_bench" --benchmark_repetitions=5 --benchmark_report_aggregates_only=true \
      --benchmark_format=json >"$raw/codec_bench.json" || { failed=1; rm -f "$raw/codec_bench.json"; }
  fi
fi

python3 "$figures" machine "$build" >"$raw/machine.json"
python3 "$figures" extract "$raw" "$raw/machine.json" "$raw/measured.json" "$committed"
if [ "$short" = 1 ]; then merged="$out/figures.json"; else merged="$committed"; fi
python3 "$figures" render "$raw/measured.json" "$doc" "$out" "$committed" "$merged"
echo "bench.sh: $(( $(date +%s) - start )) s; page $doc, charts and figures.json in $out"

if [ "$short" = 1 ]; then
  # Every table this mode measures must be in the page with numbers.
  python3 "$figures" check "$doc" relay_compare interp_sweep codec_sweep multiobject_quarter \
    multiobject_full softbody ccu ceiling messages || failed=1
  python3 "$figures" measured "$raw/measured.json" relay_compare interp_sweep codec_sweep \
    multiobject_quarter multiobject_full softbody ccu ceiling messages || failed=1
else
  # The raw JSON stays out of the tree (figures.json holds the rows).
  rm -rf "$raw"
fi
exit "$failed"
