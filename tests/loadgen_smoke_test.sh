#!/usr/bin/env bash
# Short runs of every edgephys-loadgen scenario, checking the figures the issues promise, so a
# regression in the codec, the emulations, PhyS or the SDK fails CI. These check bytes and
# errors (deterministic enough), never speed.
# Usage: loadgen_smoke_test.sh path/to/edgephys-loadgen
set -euo pipefail
lg="$1"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
cd "$work"
fail() { echo "FAIL: $*"; exit 1; }
num() { jq -r "$1" "$2"; }
le() { awk -v a="$1" -v b="$2" 'BEGIN { exit !(a <= b) }'; }

# relay-compare at 32 objects: emulations within tolerance of the paper, edgephys <= 1/4 at
# 1 mm / 0.1 degree.
"$lg" relay-compare --objects 32 --modes photon,paper,edgephys --duration 3 --receivers 1 \
  --no-progress --charts '' --json rc.json >/dev/null
for mode in photon paper edgephys; do
  ratio=$(num ".results[] | select(.mode==\"$mode\") | .ratio_to_paper" rc.json)
  case $mode in
    photon) le 0.85 "$ratio" && le "$ratio" 1.15 || fail "photon ratio $ratio outside 0.85..1.15" ;;
    paper) le 0.80 "$ratio" && le "$ratio" 1.20 || fail "paper ratio $ratio outside 0.80..1.20" ;;
    edgephys)
      le "$ratio" 0.25 || fail "edgephys ratio $ratio above 0.25"
      pos=$(num '.results[] | select(.mode=="edgephys") | .pos_err_max_m' rc.json)
      rot=$(num '.results[] | select(.mode=="edgephys") | .rot_err_max_deg' rc.json)
      le "$pos" 0.001 || fail "edgephys position error $pos m"
      le "$rot" 0.1 || fail "edgephys rotation error $rot deg" ;;
  esac
done
echo "relay-compare ok"

# Offline sweeps produce their JSON.
"$lg" interp-sweep --rates 12,30 --duration 3 --objects 4 --charts '' --json is.json >/dev/null
[ "$(jq '.results | length' is.json)" -gt 0 ] || fail "interp-sweep: no results"
"$lg" codec-sweep --steps 0.001 --rotation-bounds 0.1 --thresholds 0.0005 --objects 32 --duration 2 \
  --charts '' --json cs.json >/dev/null
[ "$(jq '.results | length' cs.json)" -gt 0 ] || fail "codec-sweep: no results"
echo "sweeps ok"

# ccu: a few bots with grabs: no reliable message lost, latency reported.
"$lg" ccu --users 8 --ramp 1 --duration 4 --no-progress --charts '' --json ccu.json >/dev/null
[ "$(num '.summary.reliable_lost' ccu.json)" = "0" ] || fail "ccu lost reliable messages"
[ "$(num '.summary.connected' ccu.json)" = "8" ] || fail "ccu: not every bot joined"
le 0.001 "$(num '.summary.latency_user_to_user_ms_p99' ccu.json)" || fail "ccu: no latency samples"
# Arrival latency ends at the kernel's receive timestamp, before the SDK reads the datagram: per
# sample never above the SDK latency (0.05 ms: steady and realtime clocks may tick at rates a
# few hundred ppm apart).
for what in latency grab_latency; do
  sdk=$(num ".summary.${what}_ms_p99" ccu.json)
  [ "$what" = latency ] && sdk=$(num '.summary.latency_user_to_user_ms_p99' ccu.json)
  arrival=$(num ".summary.${what}_arrival_ms_p99" ccu.json)
  le 0 "$arrival" && le "$arrival" "$(awk -v s="$sdk" 'BEGIN { print s + 0.05 }')" ||
    fail "ccu: $what arrival p99 $arrival ms outside 0..SDK p99 $sdk ms"
done
le 0.001 "$(num '.summary.latency_arrival_ms_p99' ccu.json)" || fail "ccu: no arrival latency samples"
echo "ccu ok"

# PhyS scenarios: a small multiobject and one bunny run end to end with errors at the lattice.
"$lg" multiobject --objects 200 --duration 2 --bench-steps 30 --bench-warmup 30 --settle-steps 30 \
  --no-progress --charts '' --json mo.json >/dev/null
ratio=$(num '.results[0].egress_mbit_per_s_per_client' mo.json)
le 0.0001 "$ratio" || fail "multiobject: no egress measured"
"$lg" softbody --bunnies 1 --duration 2 --bench-steps 30 --bench-warmup 30 --settle-steps 30 \
  --no-progress --charts '' --json sb.json >/dev/null
le 0.0001 "$(num '.results[0].egress_mbit_per_s_per_client' sb.json)" || fail "softbody: no egress"
echo "physics scenarios ok"

# ceiling: the relay with 1 and 2 I/O threads carries a small load with every client joined and
# nothing dropped between its receive thread and its shards; iperf3 measured beside it.
"$lg" ceiling --io-threads 1,2 --clients 16 --rooms 2 --warmup 0.5 --duration 1 --iperf-seconds 1 \
  --no-progress --json ce.json >/dev/null
for i in 0 1; do
  [ "$(num ".summary[$i].clients_joined" ce.json)" = "16" ] || fail "ceiling run $i: not every client joined"
  [ "$(num ".summary[$i].drops" ce.json)" = "0" ] || fail "ceiling run $i: shard queue drops"
  le 1000 "$(num ".summary[$i].relay_packets_per_s" ce.json)" || fail "ceiling run $i: relay idle"
done
if command -v iperf3 >/dev/null; then
  le 0.000001 "$(num '.summary[0].ratio_packets' ce.json)" || fail "ceiling: no iperf3 ratio"
fi
echo "ceiling ok"
echo "loadgen smoke test passed"
