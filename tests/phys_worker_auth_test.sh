#!/usr/bin/env bash
# edgephys-phys against a relay that does not seal packets (--packet-auth false): by default the
# worker refuses it (exit 1, AuthRequired: an on-path attacker stripping the relay's key must
# not downgrade a worker); with --require-packet-auth false it attaches (the relay's
# edgephys_physics_workers gauge reaches 1). Then against a sealing relay with the default.
# Usage: phys_worker_auth_test.sh RELAY PHYS
set -euo pipefail
relay_bin="$1"
phys_bin="$2"
source "$(dirname "$0")/lib.sh"  # $work, relay_pid, stop_on_exit, start_relay
worker_pid=""
stop_on_exit worker_pid
fail() { echo "FAIL: $*"; for f in "$work"/*.log; do echo "-- $f"; tail -5 "$f"; done; exit 1; }
cd "$work"
secret="phys-$RANDOM$RANDOM"
workers() {  # the relay's attached-worker gauge
  curl -sf -m 1 "http://$metrics_address/metrics" | awk '$1 == "edgephys_physics_workers" { print $2 }'
}
wait_workers() {  # N: up to 5 s for the gauge to read N
  for _ in $(seq 50); do
    [ "$(workers)" = "$1" ] && return 0
    sleep 0.1
  done
  return 1
}

start_relay_with_metrics "$relay_bin" relay1.log 60 --secret "$secret" --packet-auth false ||
  fail "edgephys-relay did not start"
status=0
EDGEPHYS_SECRET="$secret" timeout 20 "$phys_bin" --relay "$relay_address" --run-for 15 \
  >refused.log 2>&1 || status=$?
[ "$status" = 1 ] || fail "the worker did not refuse an unsealed relay (exit $status)"
grep -q "refused the worker" refused.log || fail "no refusal logged"
[ "$(workers)" = 0 ] || fail "a refused worker is counted as attached"

EDGEPHYS_SECRET="$secret" "$phys_bin" --relay "$relay_address" --run-for 30 \
  --require-packet-auth false >accepted.log 2>&1 &
worker_pid=$!
wait_workers 1 || fail "--require-packet-auth false: the worker did not attach"
stop "$worker_pid"; worker_pid=""
stop "$relay_pid"; relay_pid=""

start_relay_with_metrics "$relay_bin" relay2.log 60 --secret "$secret" ||
  fail "edgephys-relay did not start"
EDGEPHYS_SECRET="$secret" "$phys_bin" --relay "$relay_address" --run-for 30 >sealed.log 2>&1 &
worker_pid=$!
wait_workers 1 || fail "the worker did not attach to a sealing relay"
echo "PASS: edgephys-phys packet authentication"
