#!/usr/bin/env bash
# ctest bench_short: scripts/bench.sh --short into a temporary directory. Passes when the run
# measured every table of the figures page with numbers (bench.sh checks that) and left
# docs/benchmarks.md and docs/charts/ as they were.
#   short_test.sh BUILD_DIR EDGEPHYS_LOADGEN
set -euo pipefail
build="$1"
loadgen="$2"
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
out="$(mktemp -d /tmp/edgephys-bench-short.XXXXXX)"
trap 'rm -rf "$out"' EXIT
before="$(cd "$root" && cat docs/benchmarks.md docs/charts/* | sha256sum)"
"$root/scripts/bench.sh" --short --build "$build" --loadgen "$loadgen" --out "$out"
after="$(cd "$root" && cat docs/benchmarks.md docs/charts/* | sha256sum)"
if [ "$before" != "$after" ]; then
  echo "FAIL: bench.sh --short changed docs/benchmarks.md or docs/charts/"
  exit 1
fi
for chart in relay_compare ccu ceiling multiobject_full softbody interp_sweep codec_sweep; do
  [ -s "$out/$chart.png" ] || { echo "FAIL: no chart $chart.png"; exit 1; }
done
echo "bench_short passed"
