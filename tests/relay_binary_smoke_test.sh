#!/usr/bin/env bash
# Smoke test of the real edgephys-relay binary: it starts on loopback, serves Prometheus
# metrics that promtool accepts, mints tokens, and stops cleanly on SIGTERM.
# Usage: relay_binary_smoke_test.sh path/to/edgephys-relay
set -euo pipefail
relay="$1"
work=$(mktemp -d)
pid=""
cleanup() { [ -n "$pid" ] && kill "$pid" 2>/dev/null || true; rm -rf "$work"; }
trap cleanup EXIT

token=$("$relay" token --player 7 --room lobby --ttl 60)
[[ "$token" =~ ^[A-Za-z0-9_-]{80,}$ ]] || { echo "FAIL: token looks wrong: $token"; exit 1; }
if "$relay" token --room lobby >/dev/null 2>&1; then echo "FAIL: token without --player accepted"; exit 1; fi
if "$relay" --bind nonsense --run-for 1 >/dev/null 2>&1; then echo "FAIL: bad --bind accepted"; exit 1; fi

for attempt in 1 2 3 4 5; do
  port=$(( 20000 + RANDOM % 40000 ))
  "$relay" --bind 127.0.0.1:0 --metrics "127.0.0.1:$port" --run-for 60 --log-level info \
    >"$work/relay.log" 2>&1 &
  pid=$!
  for _ in $(seq 1 50); do
    if curl -fsS "http://127.0.0.1:$port/metrics" -o "$work/metrics.txt" 2>/dev/null; then break; fi
    if ! kill -0 "$pid" 2>/dev/null; then break; fi
    sleep 0.1
  done
  if [ -s "$work/metrics.txt" ]; then break; fi
  kill "$pid" 2>/dev/null || true; wait "$pid" 2>/dev/null || true; pid=""
done
[ -s "$work/metrics.txt" ] || { echo "FAIL: no metrics"; cat "$work/relay.log"; exit 1; }

for name in edgephys_rooms edgephys_clients edgephys_entities edgephys_packets_received_total \
            edgephys_bytes_sent_total edgephys_entity_updates_sent_total \
            edgephys_reliable_resends_total edgephys_rtt_seconds_bucket \
            edgephys_tick_duration_seconds_bucket edgephys_packets_rejected_total; do
  grep -q "^$name" "$work/metrics.txt" || { echo "FAIL: $name missing"; cat "$work/metrics.txt"; exit 1; }
done
if command -v promtool >/dev/null; then
  promtool check metrics <"$work/metrics.txt" || { echo "FAIL: promtool"; exit 1; }
else
  echo "note: promtool not installed; skipped the lint"
fi
grep -q "development secret" "$work/relay.log" || { echo "FAIL: no warning about the dev secret"; exit 1; }

kill -TERM "$pid"
for _ in $(seq 1 50); do kill -0 "$pid" 2>/dev/null || break; sleep 0.1; done
if kill -0 "$pid" 2>/dev/null; then echo "FAIL: relay ignored SIGTERM"; exit 1; fi
wait "$pid" || { echo "FAIL: relay exited non-zero"; cat "$work/relay.log"; exit 1; }
pid=""
echo "relay binary smoke test passed"
