#!/usr/bin/env bash
# A real Prometheus server (Debian's `prometheus`) scrapes the real edgephys-relay binary, and
# its query API returns the relay's series: edgephys_rooms from the relay's instance,
# up{job="edgephys"} == 1 and a counter that moved (edgephys_packets_received_total > 0).
# Skips (exit 0, prints SKIPPED) when /usr/bin/prometheus is not installed.
# Usage: prometheus_scrape_test.sh path/to/edgephys-relay
set -euo pipefail
relay="$1"
prometheus=${PROMETHEUS:-/usr/bin/prometheus}
deadline_s=${EDGEPHYS_SCRAPE_DEADLINE:-60}

if [ ! -x "$prometheus" ]; then
  echo "SKIPPED: $prometheus not installed (bash scripts/setup.sh installs Debian's prometheus)"
  exit 0
fi
command -v curl >/dev/null || { echo "SKIPPED: curl not installed"; exit 0; }

source "$(dirname "${BASH_SOURCE[0]}")/lib.sh"  # $work, relay_pid, stop_on_exit, wait_for_url
prom_pid=""
stop_on_exit prom_pid
fail() {
  echo "FAIL: $*"
  echo "--- relay log";      tail -n 20 "$work/relay.log" 2>/dev/null || true
  echo "--- prometheus log"; tail -n 30 "$work/prometheus.log" 2>/dev/null || true
  echo "--- last answer";    cat "$work/answer.json" 2>/dev/null || true; echo
  exit 1
}
port_free() { ! ss -Htan "sport = :$1" 2>/dev/null | grep -q .; }
pick_port() {
  local p
  for _ in $(seq 1 50); do p=$(( 20000 + RANDOM % 40000 )); port_free "$p" && { echo "$p"; return; }; done
  echo $(( 20000 + RANDOM % 40000 ))
}

# 1. The relay: ephemeral UDP port on loopback, metrics on a free TCP port (retried on a clash).
metrics_port=""
for _ in 1 2 3 4 5; do
  port=$(pick_port)
  "$relay" --bind 127.0.0.1:0 --metrics "127.0.0.1:$port" --run-for 110 --log-level info \
    >"$work/relay.log" 2>&1 &
  relay_pid=$!
  wait_for_url "http://127.0.0.1:$port/metrics" "$relay_pid" 50 && { metrics_port=$port; break; }
  stop "$relay_pid"; relay_pid=""
done
[ -n "$metrics_port" ] || fail "the relay never served /metrics"
# /metrics can answer before the relay has logged its UDP port: wait for the line (5 s at most).
udp=""
for _ in $(seq 1 50); do
  udp=$(sed -n 's/.*listening on udp 127\.0\.0\.1:\([0-9]*\).*/\1/p' "$work/relay.log" | head -n 1)
  [ -n "$udp" ] && break
  sleep 0.1
done
[ -n "$udp" ] || fail "no UDP port in the relay log"
instance="127.0.0.1:$metrics_port"

# A few junk datagrams so edgephys_packets_received_total is above zero.
for _ in 1 2 3 4 5; do printf 'not an edgephys packet' >"/dev/udp/127.0.0.1/$udp"; done

# 2. Prometheus: scrape every second, storage and consoles in the temp dir.
cat >"$work/prometheus.yml" <<EOF
global:
  scrape_interval: 1s
  evaluation_interval: 1s
scrape_configs:
  - job_name: edgephys
    scrape_interval: 1s
    scrape_timeout: 1s
    static_configs:
      - targets: ['$instance']
EOF
mkdir -p "$work/tsdb" "$work/consoles"
if [ -x "${prometheus%/*}/promtool" ]; then
  "${prometheus%/*}/promtool" check config "$work/prometheus.yml" >/dev/null \
    || fail "promtool rejects the generated prometheus.yml"
fi
prom_port=""
for _ in 1 2 3 4 5; do
  port=$(pick_port)
  "$prometheus" --config.file="$work/prometheus.yml" --storage.tsdb.path="$work/tsdb" \
    --web.listen-address="127.0.0.1:$port" \
    --web.console.templates="$work/consoles" --web.console.libraries="$work/consoles" \
    --log.level=info >"$work/prometheus.log" 2>&1 &
  prom_pid=$!
  # Up to 15 s for the TSDB and the web server.
  wait_for_url "http://127.0.0.1:$port/-/ready" "$prom_pid" 150 && { prom_port=$port; break; }
  stop "$prom_pid"; prom_pid=""
done
[ -n "$prom_port" ] || fail "prometheus never became ready"

# 3. The query API: wait (bounded) until every query returns the relay's instance.
query() {  # query <promql>: 0 when the answer is a non-empty vector holding our instance
  curl -fsS --max-time 3 -G "http://127.0.0.1:$prom_port/api/v1/query" \
    --data-urlencode "query=$1" -o "$work/answer.json" 2>/dev/null || return 1
  grep -q '"status":"success"' "$work/answer.json" &&
    grep -q "\"instance\":\"$instance\"" "$work/answer.json"
}
queries=(
  'edgephys_rooms'
  'up{job="edgephys"} == 1'
  'edgephys_packets_received_total > 0'
  'edgephys_tick_duration_seconds_count'
)
start=$(date +%s)
for q in "${queries[@]}"; do
  until query "$q"; do
    kill -0 "$relay_pid" 2>/dev/null || fail "the relay exited"
    kill -0 "$prom_pid" 2>/dev/null || fail "prometheus exited"
    [ $(( $(date +%s) - start )) -lt "$deadline_s" ] || fail "no answer to '$q' after ${deadline_s}s"
    sleep 0.5
  done
  echo "ok: $q -> $(tr -d '\n' <"$work/answer.json" | head -c 300)"
done
grep -q '"job":"edgephys"' "$work/answer.json" || fail "job label missing"

# The target page agrees: one active target, healthy.
curl -fsS --max-time 3 "http://127.0.0.1:$prom_port/api/v1/targets" -o "$work/answer.json" \
  || fail "no /api/v1/targets"
grep -q '"health":"up"' "$work/answer.json" || fail "target not healthy"

echo "prometheus scrape test passed in $(( $(date +%s) - start ))s (prometheus $("$prometheus" --version 2>&1 | head -n 1 | awk '{print $3}'))"
