#!/usr/bin/env bash
# Velocities on the wire against today's replication, on the same scenes (docs/benchmarks.md,
# "Velocities on the wire"). Runs edgephys-loadgen multiobject at one box count in two scenes
# (a quarter-plus moving; everything stirred): the old curve (format 2, lerp/slerp at the SDK's
# adaptive playout) at several ambient rates, the new one (format 12, velocities) at several
# thresholds; then tabulates egress (ratio to the paper's Obj_N) against the display error and
# charts it. Bounded: 7 points x 2 scenes = 14 runs of about 50 s each.
#   usage: scripts/velocity_sweep.sh [loadgen binary] [out dir] [objects]
set -euo pipefail
loadgen=${1:-build/default/loadgen/edgephys-loadgen}
out=${2:-velocity-sweep}
objects=${3:-1000}
mkdir -p "$out"
quarter=(--layers 1 --stirrer-reach 0.75 --stirrer-speed 1.0)
# name | extra multiobject arguments. "old_6" is today's default; "new_*" send format 12 and
# dead-reckon (position / rotation threshold, checks per second, the probe's playout delay).
points=(
  "old_12|--ambient-hz 12"
  "old_6|"
  "old_4|--ambient-hz 4"
  "new_10mm_60hz_p60|--velocities --extrapolation-threshold 0.01 --extrapolation-rotation-threshold 5 --extrapolation-max-hz 60 --playout-min-delay 0.06"
  "new_10mm|--velocities --extrapolation-threshold 0.01 --extrapolation-rotation-threshold 5"
  "new_20mm|--velocities --extrapolation-threshold 0.02 --extrapolation-rotation-threshold 8 --extrapolation-max-hz 20"
  "new_40mm|--velocities --extrapolation-threshold 0.04 --extrapolation-rotation-threshold 10 --extrapolation-max-hz 12"
)
# CHART_ONLY=1: tabulate and chart the JSON files already in the out dir.
for p in "${points[@]}"; do
  [[ ${CHART_ONLY:-0} == 1 ]] && break
  name=${p%%|*}
  read -r -a extra <<<"${p#*|}"
  for scene in quarter full; do
    args=()
    [[ $scene == quarter ]] && args=("${quarter[@]}")
    "$loadgen" multiobject --objects "$objects" --no-bench --duration 8 "${args[@]}" "${extra[@]}" \
      --charts '' --no-progress --json "$out/${scene}_${name}.json" >/dev/null
  done
done
python3 - "$out" "${points[@]}" <<'PY'
import json, sys
out, names = sys.argv[1], [p.split("|")[0] for p in sys.argv[2:]]
print("scene,point,egress_ratio_to_paper,bytes_per_update,updates_per_s,display_err_p50_mm,"
      "display_err_p99_mm,display_rot_err_p99_deg,playout_ms,err_vs_sent_max_mm,moving")
for scene in ("quarter", "full"):
    dats = {"old": open(f"{out}/{scene}_old.dat", "w"), "new": open(f"{out}/{scene}_new.dat", "w")}
    for name in names:
        r = json.load(open(f"{out}/{scene}_{name}.json"))["results"][0]
        row = [r["egress_ratio_to_paper"], r["bytes_per_update"], r["updates_per_s_per_client"],
               r["display_err_p50_m"] * 1e3, r["display_err_p99_m"] * 1e3,
               r["display_rot_err_p99_deg"], r["display_playout_ms_median"],
               r["pos_err_sent_max_m"] * 1e3, r["relay_moving_fraction"]]
        print(scene, name, *(f"{x:.3f}" for x in row), sep=",")
        dats["old" if name.startswith("old") else "new"].write(
            f"{row[0]:.4f} {row[4]:.3f} {row[3]:.3f} {name}\n")
PY
if command -v gnuplot >/dev/null; then
  for term in "pngcairo size 900,560:png" "svg size 900,560:svg"; do
    gnuplot <<GP
set terminal ${term%%:*}
set output '$out/velocity_tradeoff.${term##*:}'
set title 'Egress vs what a receiver displays: format 2 (lerp) vs format 12 (velocities), $objects boxes'
set xlabel 'egress per client / paper Obj_$objects'
set ylabel 'display error p99 vs truth (mm)'
set key top right
set grid
set termoption noenhanced
plot '$out/quarter_old.dat' using 1:2 with linespoints pt 7 title 'quarter-plus, format 2 (ambient Hz)', \
     '' using 1:2:4 with labels font ',8' offset 0,0.8 notitle, \
     '$out/quarter_new.dat' using 1:2 with linespoints pt 5 title 'quarter-plus, format 12', \
     '' using 1:2:4 with labels font ',8' offset 0,-0.8 notitle, \
     '$out/full_old.dat' using 1:2 with linespoints pt 9 title 'full stir, format 2 (ambient Hz)', \
     '' using 1:2:4 with labels font ',8' offset 0,0.8 notitle, \
     '$out/full_new.dat' using 1:2 with linespoints pt 11 title 'full stir, format 12', \
     '' using 1:2:4 with labels font ',8' offset 0,-0.8 notitle
GP
  done
fi
