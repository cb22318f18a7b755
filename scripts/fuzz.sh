#!/usr/bin/env bash
# Builds the libFuzzer targets (tests/fuzz) with clang under ASan + UBSan in build/fuzz and
# runs each for a bounded time on a temporary copy of its seed corpus (tests/fuzz/corpus), so
# the repository is never modified. Exit status: non-zero if any target found a crash, leak,
# timeout, out-of-memory or sanitizer report (its log tail and reproducer are printed).
#
# Environment: FUZZ_SECONDS (per target, default 20), FUZZ_JOBS (build jobs, default 2),
# FUZZ_TARGETS (space-separated subset), FUZZ_BUILD_DIR (default build/fuzz),
# FUZZ_KEEP_DIR (copy crash artifacts and logs there), FUZZ_SKIP_CAPI=1 (skip the C API's
# sanitized bad-argument test, sdk/c_api_test.cc, which runs before the fuzzers).
# Reproduce a finding: build/fuzz/tests/fuzz/<target> <artifact file>
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
build=${FUZZ_BUILD_DIR:-$root/build/fuzz}
seconds=${FUZZ_SECONDS:-20}
jobs=${FUZZ_JOBS:-2}
read -r -a targets <<< "${FUZZ_TARGETS:-packet_fuzz reliable_fuzz state_fuzz message_fuzz http_head_fuzz}"

cc=${CC:-}; cxx=${CXX:-}
if [[ -z "$cxx" || "$cxx" != *clang* ]]; then
  if command -v clang++ >/dev/null; then cc=clang; cxx=clang++; else cc=clang-14; cxx=clang++-14; fi
fi
generator=()
if [[ ! -f "$build/CMakeCache.txt" ]] && command -v ninja >/dev/null; then generator=(-G Ninja); fi

echo "== configuring $build ($cxx)"
CC=$cc CXX=$cxx cmake -S "$root" -B "$build" "${generator[@]}" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DEDGEPHYS_BUILD_FUZZ=ON -DEDGEPHYS_BUILD_TESTS=ON -DEDGEPHYS_BUILD_BENCH=OFF >/dev/null
echo "== building ${targets[*]} (-j$jobs)"
cmake --build "$build" -j "$jobs" --target "${targets[@]}"

# The C API's bad-argument test under the same ASan + UBSan (include/edgephys/edgephys.h).
if [[ "${FUZZ_SKIP_CAPI:-0}" != "1" ]]; then
  echo "== c_api_sanitized_test (ASan + UBSan)"
  cmake --build "$build" -j "$jobs" --target c_api_sanitized_test
  ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$build/sdk/c_api_sanitized_test" --gtest_brief=1 || { echo "!! c_api_sanitized_test FAILED"; exit 1; }
fi

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
export ASAN_OPTIONS=${ASAN_OPTIONS:-detect_leaks=1:abort_on_error=1:allocator_may_return_null=0}
export UBSAN_OPTIONS=${UBSAN_OPTIONS:-print_stacktrace=1:halt_on_error=1}

failed=()
for t in "${targets[@]}"; do
  bin="$build/tests/fuzz/$t"
  mkdir -p "$work/$t/corpus" "$work/$t/artifacts"
  if [[ -d "$root/tests/fuzz/corpus/$t" ]]; then cp -r "$root/tests/fuzz/corpus/$t/." "$work/$t/corpus/"; fi
  echo "== $t: ${seconds}s"
  status=0
  "$bin" -max_total_time="$seconds" -rss_limit_mb=2048 -timeout=10 -max_len=4096 \
         -print_final_stats=1 -artifact_prefix="$work/$t/artifacts/" \
         "$work/$t/corpus" > "$work/$t/log" 2>&1 || status=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$work/$t/log" | tail -1)
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$work/$t/log" | tail -1)
  cov=$(grep -o 'cov: [0-9]*' "$work/$t/log" | tail -1 || true)
  if [[ $status -ne 0 ]] || ls "$work/$t/artifacts/"* >/dev/null 2>&1; then
    echo "!! $t FAILED (exit $status)"
    tail -n 60 "$work/$t/log"
    for a in "$work/$t/artifacts/"*; do
      [[ -f "$a" ]] || continue
      echo "-- reproducer $(basename "$a") (base64):"
      base64 -w0 "$a"; echo
    done
    failed+=("$t")
  else
    echo "   ok: ${execs:-?} runs, ${rate:-?} exec/s, ${cov:-cov: ?}"
  fi
  if [[ -n "${FUZZ_KEEP_DIR:-}" ]]; then mkdir -p "$FUZZ_KEEP_DIR"; cp -r "$work/$t" "$FUZZ_KEEP_DIR/"; fi
done

if [[ ${#failed[@]} -ne 0 ]]; then
  echo "fuzzing found problems in: ${failed[*]}"
  exit 1
fi
echo "fuzzing: all targets ran without findings"
