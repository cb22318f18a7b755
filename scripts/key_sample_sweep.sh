#!/usr/bin/env bash
# Key samples against the fixed ambient rate on the same scenes (docs/benchmarks.md, "Key
# samples", sessions 8, 9 and 11): edgephys-loadgen multiobject at 1,000 boxes on the quarter-plus and
# full-stir scenes, one JSON per (scene, point, repeat), then per point the median over repeats
# of egress, key samples per box per s and the display error under both yardsticks (and, last,
# the arrival-yardstick error of the same receiver drawing kHermite instead, session 15, and the
# same receiver at the adaptive playout alone, what the SDK did before session 16). Bounded:
# points x 2 scenes x REPEAT runs of about 10 s each. Hold /tmp/edgephys-bench.lock and
# /tmp/edgephys-build.lock around it.
#   usage: scripts/key_sample_sweep.sh [loadgen] [out dir] [REPEAT] ["name|args" ...]
set -euo pipefail
loadgen=${1:-build/default/loadgen/edgephys-loadgen}
out=${2:-key-sample-sweep}
repeat=${3:-1}
shift $(( $# < 3 ? $# : 3 ))
points=("$@")
if (( ${#points[@]} == 0 )); then
  # Session 11's medians (docs/benchmarks.md, "Display error, session 11"; format 13, 30 Hz
  # checks unless c0; s = fixed rate stamped with state_time, A = key samples stamped with the
  # relay's mean PhyS lag). Session 9's were fixed6, k10r5_025c0, k20r20_1, k15r8_05 and k30_1;
  # session 8's fixed6, k10r5_025, k10r5_03 and k20r8_05.
  A="--key-samples-arrival-stamp"
  points=(
    "fixed6|"
    "fixed6s|--stamp-state-time"
    "k10r5_025c0|--key-samples 0.01 --key-samples-rotation 5 --key-samples-max-interval 0.25 --key-samples-check-hz 0"
    "k10r5_025c0A|--key-samples 0.01 --key-samples-rotation 5 --key-samples-max-interval 0.25 --key-samples-check-hz 0 $A"
    "k15r8_05A|--key-samples 0.015 --key-samples-rotation 8 --key-samples-max-interval 0.5 $A"
    "k20r20_1A|--key-samples 0.02 --key-samples-rotation 20 --key-samples-max-interval 1 $A"
    "k30_1A|--key-samples 0.03 --key-samples-rotation 10 --key-samples-max-interval 1 $A"
  )
fi
quarter=(--layers 1 --stirrer-reach 0.75 --stirrer-speed 1.0)
for ((i = 1; i <= repeat; i++)); do
  for p in "${points[@]}"; do
    name=${p%%|*}
    read -r -a extra <<<"${p#*|}"
    for scene in quarter full; do
      args=()
      [[ $scene == quarter ]] && args=("${quarter[@]}")
      mkdir -p "$out/run$i"
      "$loadgen" multiobject --objects 1000 --no-bench --duration 8 "${args[@]}" "${extra[@]}" \
        --charts '' --no-progress --json "$out/run$i/${scene}_${name}.json" >/dev/null
    done
  done
done
python3 - "$out" "$repeat" "${points[@]}" <<'PY'
import json, statistics, sys
out, repeat, names = sys.argv[1], int(sys.argv[2]), [p.split("|")[0] for p in sys.argv[3:]]
keys = ["egress_ratio_to_paper", "bytes_per_update", "updates_per_s_per_client",
        "key_strayed_per_box_s", "key_interval_per_box_s", "display_err_p50_m", "display_err_p99_m",
        "display_err_state_p99_m", "display_rot_err_p99_deg", "display_playout_ms_median",
        "pos_err_sent_max_m", "display_err_hermite_p50_m", "display_err_hermite_p99_m",
        "display_err_adaptive_p50_m", "display_err_adaptive_p99_m",
        "display_adaptive_playout_ms_median"]
# Where a state's bytes go (RelayCounters::state_record_bits): a record's mean bits, its
# reference symbol's and residuals' (position + rotation), and the datagram overhead per update.
def coding(r):
    share, bits = r.get("record_share", [0, 0, 0]), r.get("record_bits", [[0] * 6] * 3)
    rec = sum(s * sum(b) for s, b in zip(share, bits))
    return {"record_bits": rec, "reference_bits": sum(s * b[1] for s, b in zip(share, bits)),
            "residual_bits": sum(s * (b[4] + b[5]) for s, b in zip(share, bits)),
            "overhead_bytes": r["bytes_per_update"] - rec / 8}
extra = ["record_bits", "reference_bits", "residual_bits", "overhead_bytes"]
print("scene,point," + ",".join(keys + extra))
for scene in ("quarter", "full"):
    for name in names:
        runs = [json.load(open(f"{out}/run{i}/{scene}_{name}.json"))["results"][0]
                for i in range(1, repeat + 1)]
        for r in runs:
            r.update(coding(r))
        print(scene, name, *(f"{statistics.median(r[k] for r in runs):.4f}" for k in keys + extra),
              sep=",")
PY
