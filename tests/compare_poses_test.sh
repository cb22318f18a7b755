#!/usr/bin/env bash
# Tests compare_poses.awk (the SDK example test's check that the watcher saw the example's
# poses within 1 mm and 0.1 degree) on fixed logs: a pose equal to its own printed copy passes
# whatever the rounding of its quaternion's norm; 0.15 degree, 1.5 mm, a missing entity and
# too few poses fail; 0.05 degree and 0.5 mm pass; a sign-flipped quaternion is the same
# rotation.
set -euo pipefail
awkfile="$(dirname "$0")/compare_poses.awk"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
failures=0
# expect PASS|FAIL NAME WATCHER_POSES EXAMPLE_POSES
expect() {
  local want="$1" name="$2"
  printf '%s\n' "$3" >"$work/w"
  printf '%s\n' "$4" >"$work/e"
  local got=PASS
  awk -f "$awkfile" "$work/w" "$work/e" >"$work/out" 2>&1 || got=FAIL
  if [ "$got" != "$want" ]; then
    echo "FAIL: $name: expected $want, got $got"; cat "$work/out"; failures=$((failures + 1))
  else
    echo "ok: $name ($got)"
  fi
}
a="pose 1 0.000047 0.100047 0.000047 0.000000 0.000000 0.000503 1.000000"
b="pose 2 -0.000953 0.300048 0.000047 0.000000 0.000000 0.000000 1.000000"
# |q|^2 = 1 - 3.86e-7 as printed (a box that failed the comparison; 0.1006 degree against
# itself with the unnormalised formula).
c="pose 3 1.363048 0.100047 -0.001953 0.000503 -0.003018 0.000503 0.999995"
# |q|^2 = 1 + 8.96e-7 as printed.
d="pose 3 1.368048 0.100047 -0.001953 0.000503 -0.003520 0.000503 0.999994"
base="$a
$b"
# expect3 PASS|FAIL NAME WATCHER_POSE EXAMPLE_POSE: both logs hold $base, then the pose given.
expect3() {
  expect "$1" "$2" "$base
$3" "$base
$4"
}
expect3 PASS "identical poses" "$c" "$c"
expect3 PASS "identical poses, norm above 1" "$d" "$d"
expect PASS "watcher lines among other output" "watching
$base
DBG other
$c
ok" "spawned
$base
$c
ok"
# 0.05 degree about y: (0, sin(0.025 deg), 0, cos(0.025 deg)).
expect3 PASS "0.05 degree apart" "pose 3 0 0.1 0 0 0 0 1" \
  "pose 3 0 0.1 0 0.000000 0.000436 0.000000 1.000000"
# 0.15 degree about y.
expect3 FAIL "0.15 degree apart" "pose 3 0 0.1 0 0 0 0 1" \
  "pose 3 0 0.1 0 0.000000 0.001309 0.000000 0.999999"
expect3 PASS "sign-flipped quaternion" "pose 3 0 0.1 0 0.000503 -0.003018 0.000503 0.999995" \
  "pose 3 0 0.1 0 -0.000503 0.003018 -0.000503 -0.999995"
expect3 PASS "0.5 mm apart" "pose 3 0 0.1 0 0 0 0 1" \
  "pose 3 0.0005 0.1 0 0 0 0 1"
expect3 FAIL "1.5 mm apart" "pose 3 0 0.1 0 0 0 0 1" \
  "pose 3 0.0015 0.1 0 0 0 0 1"
expect FAIL "entity the watcher never saw" "$base" "$base
$c"
expect FAIL "fewer than 3 poses" "$base" "$base"
expect3 FAIL "garbage rotation" "pose 3 0 0.1 0 0 0 0 0" \
  "pose 3 0 0.1 0 0 0 0 0"
[ "$failures" -eq 0 ] || { echo "$failures case(s) failed"; exit 1; }
echo "compare_poses ok"
