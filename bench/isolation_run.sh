#!/usr/bin/env bash
# One `isolation` run against edgephys-relay as its own process (docs/operations.md recipe),
# printing one line: A's p99 with B / alone (SDK, socket), the p99s, relay CPU, B's step, late joiner.
#   bench/isolation_run.sh BUILD_DIR OUT.json PHYSICS_NICE [isolation options...]
# e.g. bench/isolation_run.sh build/default iso.json 19 --b-decode joiner
# Hold /tmp/edgephys-bench.lock and /tmp/edgephys-build.lock around it. Ports are picked free;
# the relay is stopped by its PID; the run is bounded by isolation's own hard end (and --run-for).
set -euo pipefail
build=$1; out=$2; nice=$3; shift 3
relay_bin=${RELAY_BIN:-$build/relay/edgephys-relay}
loadgen_bin=${LOADGEN_BIN:-$build/loadgen/edgephys-loadgen}
read -r port mport < <(python3 -c 'import socket
a=socket.socket(socket.AF_INET,socket.SOCK_DGRAM);a.bind(("127.0.0.1",0))
b=socket.socket();b.bind(("127.0.0.1",0));print(a.getsockname()[1],b.getsockname()[1])')
log=$(mktemp /tmp/isolation-relay.XXXXXX.log)
"$relay_bin" --bind 127.0.0.1:$port --metrics 127.0.0.1:$mport --secret S --admin-addr off \
  --max-connections-per-address 1024 --max-handshakes-per-s 10000 --max-spawns-per-s 0 \
  --max-packets-per-s 0 --max-bytes-per-s 0 --max-entities-per-player 10100 \
  --max-player-bodies 10100 --max-room-bodies 10100 --physics-threads ${PHYSICS_THREADS:-2} --physics-nice "$nice" \
  ${RELAY_FLAGS:-} --run-for 400 >"$log" 2>&1 &
relay=$!
trap 'kill $relay 2>/dev/null || true' EXIT
for _ in $(seq 100); do
  curl -sf "http://127.0.0.1:$mport/metrics" >/dev/null 2>&1 && break
  sleep 0.1
done
"$loadgen_bin" isolation --relay 127.0.0.1:$port --secret S --metrics 127.0.0.1:$mport \
  --relay-pid $relay --phase 10 --no-after --charts '' --no-progress --json "$out" "$@" >/dev/null
kill $relay 2>/dev/null || true
wait $relay 2>/dev/null || true
trap - EXIT
rm -f "$log"
python3 - "$out" <<'PY'
import json, sys
j = json.load(open(sys.argv[1])); s = j["summary"]; ph = {p["name"]: p for p in j["phases"]}
a, b = ph["alone"], ph["with_b"]
f = lambda x: "nan" if x is None else f"{x:.2f}"
print(f"ratio sdk {f(s['p99_ratio_with_b_to_alone'])} socket {f(s['arrival_p99_ratio_with_b_to_alone'])} | "
      f"alone p99 {f(a['latency_ms_p99'])}/{f(a['arrival_latency_ms_p99'])} with_b {f(b['latency_ms_p99'])}/{f(b['arrival_latency_ms_p99'])} ms | "
      f"delivered {f(b['delivered_fraction'])} | relay cpu {f(a['relay_cpu'])}->{f(b['relay_cpu'])} | "
      f"step {f(b['physics_step_ms_mean'])} burn {f(s.get('burn_step_ms_mean'))} | late {f(s['late_join_s'])} s | b_ok {s['b_ok']}")
PY
