#!/usr/bin/env bash
# Runs one SDK example (examples/: C, C++, Python or C#) against a real edgephys-relay process
# on a free loopback port, with a second client (the C++ example in --watch mode) in the same
# room. Passes when the example passes its own checks (the offloaded boxes fall and settle, the
# grab gives Grabbed, collision exit, Released, collision enter, in that order; it prints "ok"),
# the watcher received the example's chat line (an application message from player 1), both
# agreed on the same "current step" (compare-and-set), the example's baton was handed to the
# watcher and its state came back from there, and the watcher saw
# every box the example reports at the same pose within the codec's bounds (1 mm, 0.1 degree).
# Usage: sdk_examples_test.sh <edgephys-relay> <stack_and_grab_cpp> <example command...>
#   (the example is called with three more arguments: relay address, join token, room)
# Prints SKIPPED (exit 0) when the example's runtime is missing (mono, python3).
set -euo pipefail
relay="$1"; watcher="$2"; shift 2
source "$(dirname "$0")/lib.sh"  # $work, relay_pid, stop_on_exit, start_relay
skip_unless_runtime "$1"
watch_pid=""
stop_on_exit watch_pid

start_relay "$relay" "$work/relay.log" 120 || exit 1
address="$relay_address"
room="sdk$RANDOM"
token1=$("$relay" token --dev-secret --player 1 --room "$room" --ttl 300)
token2=$("$relay" token --dev-secret --player 2 --room "$room" --ttl 300)

"$watcher" "$address" "$token2" "$room" --watch >"$work/watch.log" 2>&1 &
watch_pid=$!
for _ in $(seq 1 50); do grep -q "^watching" "$work/watch.log" && break; sleep 0.1; done
grep -q "^watching" "$work/watch.log" || { echo "FAIL: the watcher did not join"; cat "$work/watch.log"; exit 1; }

status=0
timeout 90 "$@" "$address" "$token1" "$room" >"$work/example.log" 2>&1 || status=$?
cat "$work/example.log"
[ "$status" -eq 0 ] && grep -q "^ok$" "$work/example.log" || { echo "FAIL: the example failed (exit $status)"; cat "$work/relay.log"; exit 1; }
for _ in $(seq 1 100); do kill -0 "$watch_pid" 2>/dev/null || break; sleep 0.1; done
wait "$watch_pid" || { echo "FAIL: the watcher failed"; cat "$work/watch.log"; exit 1; }
watch_pid=""

# The example's chat line reached the watcher, from player 1.
grep -q "^chat from 1: hello from the .* example$" "$work/watch.log" ||
  { echo "FAIL: the watcher got no chat line from the example"; cat "$work/watch.log"; exit 1; }
# The shared "current step": the example and the watcher proposed at once with compare-and-set;
# both print the one the relay took, and it is the same.
ex_step=$(grep -m1 '^agreed step: ' "$work/example.log" || true)
watch_step=$(grep -m1 '^agreed step: ' "$work/watch.log" || true)
[ -n "$ex_step" ] && [ "$ex_step" = "$watch_step" ] ||
  { echo "FAIL: no agreed step (example: '$ex_step', watcher: '$watch_step')"; exit 1; }
case "$ex_step" in "agreed step: 1 (written by player 1)"|"agreed step: 2 (written by player 2)") ;;
  *) echo "FAIL: the agreed step is neither proposal: $ex_step"; exit 1 ;; esac
# The handoff: the example handed its baton to the watcher (player 2), which got it and whose
# state of it the example then received.
baton=$(sed -n 's/^handoff: entity \([0-9]*\) to player 2, .*/\1/p' "$work/example.log")
[ -n "$baton" ] || { echo "FAIL: the example printed no handoff to player 2"; exit 1; }
grep -q "^handoff: got entity $baton$" "$work/watch.log" ||
  { echo "FAIL: the watcher did not get entity $baton"; cat "$work/watch.log"; exit 1; }
echo "$ex_step; handoff of entity $baton to player 2"
# Every pose the example printed, seen by the watcher within 1 mm and 0.1 degree.
awk -f "$(dirname "$0")/compare_poses.awk" "$work/watch.log" "$work/example.log"
echo "sdk example passed: $*"
