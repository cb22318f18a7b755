#!/usr/bin/env bash
# edgephys-loadgen hostile against the real edgephys-relay binary on loopback (its /metrics):
# every attack class runs briefly, and each is refused with its reason while the honest clients
# of both rooms stay connected and keep receiving. Checks counts and reasons, never speed.
# Usage: loadgen_hostile_test.sh LOADGEN RELAY
set -euo pipefail
lg="$1"
relay_bin="$2"
work=$(mktemp -d)
relay_pid=""
cleanup() {
  if [ -n "$relay_pid" ]; then kill "$relay_pid" 2>/dev/null || true; fi
  rm -rf "$work"
}
trap cleanup EXIT
fail() { echo "FAIL: $*"; [ -f "$work/relay.log" ] && tail -20 "$work/relay.log"; exit 1; }
cd "$work"

free_port() {  # a random port nothing listens on ($1: -u UDP or -t TCP)
  local p
  for _ in $(seq 100); do
    p=$((20000 + RANDOM % 40000))
    [ -z "$(ss -Hln "$1" "sport = :$p" 2>/dev/null)" ] && { echo "$p"; return; }
  done
  return 1
}
secret="hostile-$RANDOM$RANDOM"
for attempt in 1 2 3; do  # a port taken between the check and the bind: try others
  udp_port=$(free_port -u) && tcp_port=$(free_port -t) || fail "no free port"
  "$relay_bin" --bind "127.0.0.1:$udp_port" --metrics "127.0.0.1:$tcp_port" --secret "$secret" \
    --run-for 120 --log-level warn >relay.log 2>&1 &
  relay_pid=$!
  up=""
  for _ in $(seq 50); do  # up to 5 s for /metrics to answer
    if curl -sf -m 1 "http://127.0.0.1:$tcp_port/metrics" >/dev/null; then up=1; break; fi
    kill -0 "$relay_pid" 2>/dev/null || break
    sleep 0.1
  done
  [ -n "$up" ] && break
  kill "$relay_pid" 2>/dev/null || true
  relay_pid=""
done
[ -n "$relay_pid" ] || fail "edgephys-relay did not start"

# Small attacks (4 soft bodies: 2 fit the default per-player particle budget; 2 huge names).
timeout 100 "$lg" hostile --phase 1 --honest 2 --soft-bodies 4 --huge-names 2 --flood-rate 2000 \
  --relay "127.0.0.1:$udp_port" --secret "$secret" --metrics "127.0.0.1:$tcp_port" \
  --no-progress --json hostile.json >hostile.txt 2>&1 || { cat hostile.txt; fail "hostile exited with an error"; }
cat hostile.txt

python3 - <<'EOF' || fail "hostile's figures"
import json, sys
j = json.load(open("hostile.json"))
want = {  # attack -> refusal series that must have moved during it
    "physics": ["budget_refusals{player_particles}", "requests_rejected{over_budget}"],
    "names": ["budget_refusals{name_length}", "requests_rejected{over_budget}"],
    "churn": ["budget_refusals{player_entities}"],
    "flood": ["packets_rejected{rate_limited}"],
    "forged": ["packets_rejected{bad_auth}", "packets_rejected{replayed}"],
    "invalid": ["requests_rejected{invalid_message}", "requests_rejected{unknown_entity}",
                "entity_updates_rejected{invalid_value}"],
}
errors = []
seen = {a["attack"]: a for a in j["attacks"]}
for name, series in want.items():
    a = seen.get(name)
    if a is None or not a["ran"]:
        errors.append(f"{name}: did not run ({a and a.get('error')})")
        continue
    x = a["attack_phase"]
    for s in series:
        if x["refusals"].get(s, 0) <= 0:
            errors.append(f"{name}: no {s} in {x['refusals']}")
    for room in ("same", "other"):
        r = x[room]
        if r["connected"] != r["members"]:
            errors.append(f"{name}: honest {room}-room clients disconnected: {r}")
        if r["updates"] <= 0:
            errors.append(f"{name}: honest {room}-room clients received nothing")
    if not x["probe"]["complete"]:
        errors.append(f"{name}: the late joiner did not get the room: {x['probe']}")
if "metrics_error" in j:
    errors.append("metrics: " + j["metrics_error"])
for e in errors:
    print("FAIL:", e)
sys.exit(1 if errors else 0)
EOF
echo "PASS: loadgen hostile against the relay binary"
