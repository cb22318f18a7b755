#!/usr/bin/env bash
# edgephys-loadgen hostile against the real edgephys-relay binary on loopback (its /metrics):
# every attack class runs briefly, and each is refused with its reason while the honest clients
# of both rooms stay connected and keep receiving. Checks counts and reasons, never speed.
# Usage: loadgen_hostile_test.sh LOADGEN RELAY
set -euo pipefail
lg="$1"
relay_bin="$2"
source "$(dirname "$0")/lib.sh"  # $work, relay_pid, stop_on_exit, start_relay
fail() { echo "FAIL: $*"; [ -f "$work/relay.log" ] && tail -20 "$work/relay.log"; exit 1; }
cd "$work"

secret="hostile-$RANDOM$RANDOM"
start_relay_with_metrics "$relay_bin" relay.log 120 --secret "$secret" || fail "edgephys-relay did not start"

# Small attacks (4 soft bodies: 2 fit the default per-player particle budget; 2 huge names).
timeout 100 "$lg" hostile --phase 1 --honest 2 --soft-bodies 4 --huge-names 2 --flood-rate 2000 \
  --relay "$relay_address" --secret "$secret" --metrics "$metrics_address" \
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
