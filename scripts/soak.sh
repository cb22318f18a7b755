#!/usr/bin/env bash
# Soak test (issue #5 item 6): the real edgephys-relay binary and soak_driver's 200 SDK bots
# churning through rooms (join a random room, spawn 4 entities, move them, leave after 5-30 s,
# rejoin another) for SOAK_SECONDS (default 600). Every 10 s it samples the relay's RSS
# (/proc/<pid>/status VmRSS) and edgephys_rooms / edgephys_clients from /metrics.
# Passes when:
#   - the driver reports no reliable message lost (every spawn seen exactly once) and no
#     session dropped;
#   - after everyone leaves and the room TTL (--room-ttl 5) passes, edgephys_rooms and
#     edgephys_clients are 0 (no room or client leaked);
#   - memory is flat: the max RSS of the last third of the samples is at most the first
#     third's max + SOAK_RSS_SLACK_PCT (default 10) percent.
# Env: SOAK_SECONDS (600), SOAK_BOTS (200), SOAK_ROOMS (40), SOAK_RSS_SLACK_PCT (10),
#      SOAK_SAMPLE_S (10), SOAK_SERIES (file to copy the samples to).
# Usage: scripts/soak.sh [path/to/edgephys-relay [path/to/soak_driver]]
#        (defaults: build/soak/relay/edgephys-relay, build/soak/tests/soak/soak_driver)
set -uo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
relay_bin=${1:-$root/build/soak/relay/edgephys-relay}
driver_bin=${2:-$root/build/soak/tests/soak/soak_driver}
seconds=${SOAK_SECONDS:-600}
bots=${SOAK_BOTS:-200}
rooms=${SOAK_ROOMS:-40}
slack=${SOAK_RSS_SLACK_PCT:-10}
sample_s=${SOAK_SAMPLE_S:-10}
room_ttl=5
secret="soak-secret-$$-$RANDOM"
for b in "$relay_bin" "$driver_bin"; do
  [ -x "$b" ] || { echo "FAIL: $b not built (cmake --build <dir> --target edgephys-relay soak_driver)"; exit 2; }
done
command -v curl >/dev/null || { echo "FAIL: curl not installed"; exit 2; }

work=$(mktemp -d)
relay_pid=""
driver_pid=""
# shellcheck source=lib/stop_process.sh
source "$(dirname "${BASH_SOURCE[0]}")/lib/stop_process.sh"  # stop <pid> [seconds]
cleanup() { stop "$driver_pid"; stop "$relay_pid"; rm -rf "$work"; }
trap cleanup EXIT
trap 'exit 130' INT TERM
fail() {
  echo "FAIL: $*"
  echo "--- relay log (tail)";  tail -n 20 "$work/relay.log" 2>/dev/null || true
  echo "--- driver log (tail)"; tail -n 20 "$work/driver.log" 2>/dev/null || true
  exit 1
}
port_free() { ! ss -Hanu "sport = :$1" 2>/dev/null | grep -q . && ! ss -Hant "sport = :$1" 2>/dev/null | grep -q .; }
pick_port() {
  local p
  for _ in $(seq 1 50); do p=$(( 20000 + RANDOM % 40000 )); port_free "$p" && { echo "$p"; return; }; done
  echo $(( 20000 + RANDOM % 40000 ))
}
metrics_port=""
metric() {  # metric <name>
  curl -fsS --max-time 2 "http://127.0.0.1:$metrics_port/metrics" 2>/dev/null |
    awk -v n="$1" '$1 == n { print $2; exit }'
}

# 1. The relay: all bots come from 127.0.0.1, so the per-address limits are raised.
udp_port=""
for _ in 1 2 3 4 5; do
  udp_port=$(pick_port); metrics_port=$(pick_port)
  "$relay_bin" --bind "127.0.0.1:$udp_port" --metrics "127.0.0.1:$metrics_port" --secret "$secret" \
    --room-ttl "$room_ttl" --max-clients 4096 --max-connections-per-address 4096 \
    --max-handshakes-per-s 5000 --log-level warn --run-for $(( seconds + 300 )) \
    >"$work/relay.log" 2>&1 &
  relay_pid=$!
  for _ in $(seq 1 50); do
    [ -n "$(metric edgephys_rooms)" ] && break
    kill -0 "$relay_pid" 2>/dev/null || break
    sleep 0.1
  done
  [ -n "$(metric edgephys_rooms)" ] && break
  stop "$relay_pid"; relay_pid=""
done
[ -n "$relay_pid" ] || fail "the relay did not start"
rss_kb() { awk '/^VmRSS:/ { print $2 }' "/proc/$relay_pid/status" 2>/dev/null; }
echo "soak: relay pid $relay_pid udp 127.0.0.1:$udp_port metrics :$metrics_port;" \
     "$bots bots, $rooms rooms, ${seconds}s, RSS at start $(rss_kb) kB"

# 2. The churn driver; samples every sample_s seconds while it runs.
"$driver_bin" --relay "127.0.0.1:$udp_port" --secret "$secret" --bots "$bots" --rooms "$rooms" \
  --seconds "$seconds" >"$work/driver.json" 2>"$work/driver.log" &
driver_pid=$!
start=$(date +%s)
deadline=$(( start + seconds + 120 ))
: >"$work/series"
next=$(( start + sample_s ))
while kill -0 "$driver_pid" 2>/dev/null; do
  now=$(date +%s)
  [ "$now" -lt "$deadline" ] || fail "the driver did not finish within $(( seconds + 120 ))s"
  kill -0 "$relay_pid" 2>/dev/null || fail "the relay died"
  if [ "$now" -ge "$next" ] && [ $(( now - start )) -le "$seconds" ]; then
    line="$(( now - start )) $(rss_kb) $(metric edgephys_rooms) $(metric edgephys_clients)"
    echo "$line" >>"$work/series"
    echo "sample: t=$(( now - start ))s rss_kb=$(echo "$line" | cut -d' ' -f2) rooms=$(echo "$line" | cut -d' ' -f3) clients=$(echo "$line" | cut -d' ' -f4)"
    next=$(( next + sample_s ))
  fi
  sleep 0.5
done
wait "$driver_pid"; driver_rc=$?
driver_pid=""
summary=$(cat "$work/driver.json")
echo "driver: $summary (exit $driver_rc)"
grep -E "never saw|dropped|could not connect" "$work/driver.log" | head -n 10

# 3. No leak: after the room TTL every room and client is gone (bounded wait).
rooms_left="" clients_left=""
for _ in $(seq 1 $(( (room_ttl + 15) * 2 ))); do
  rooms_left=$(metric edgephys_rooms); clients_left=$(metric edgephys_clients)
  [ "$rooms_left" = "0" ] && [ "$clients_left" = "0" ] && break
  sleep 0.5
done
end_rss=$(rss_kb)
echo "after all left + room TTL: rooms=$rooms_left clients=$clients_left rss_kb=$end_rss"

# 4. Flat memory: last third's max vs first third's max.
n=$(wc -l <"$work/series")
[ "$n" -ge 3 ] || fail "only $n RSS samples (SOAK_SECONDS too short for SOAK_SAMPLE_S)"
third=$(( n / 3 ))
first_max=$(head -n "$third" "$work/series" | awk 'm < $2 { m = $2 } END { print m }')
last_max=$(tail -n "$third" "$work/series" | awk 'm < $2 { m = $2 } END { print m }')
echo "rss series (kB): $(awk '{ printf "%s%s", sep, $2; sep = " " }' "$work/series")"
echo "rss first-third max ${first_max} kB, last-third max ${last_max} kB (limit +${slack}%)"
[ -n "${SOAK_SERIES:-}" ] && cp "$work/series" "$SOAK_SERIES"

[ "$driver_rc" -eq 0 ] || fail "the driver reported loss, duplicates or dropped sessions: $summary"
[ "$rooms_left" = "0" ] || fail "edgephys_rooms=$rooms_left after everyone left and the TTL passed (room leak)"
[ "$clients_left" = "0" ] || fail "edgephys_clients=$clients_left after everyone left (client leak)"
awk -v f="$first_max" -v l="$last_max" -v s="$slack" 'BEGIN { exit !(l <= f * (1 + s / 100)) }' ||
  fail "RSS grew: last third max $last_max kB > first third max $first_max kB + $slack%"
echo "soak passed: ${seconds}s, $bots bots, no reliable loss, no room leaked, RSS flat"
