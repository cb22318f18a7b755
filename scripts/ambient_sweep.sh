#!/usr/bin/env bash
# Egress against display accuracy as the relay's ambient rate varies (docs/benchmarks.md,
# "Ambient rate"). Runs edgephys-loadgen multiobject at one box count for each ambient rate, in
# two scenes (a quarter-plus moving; everything stirred), and charts the ratio to the paper
# against the receiver's display error. Bounded: 8 runs of about 30 s.
#   usage: scripts/ambient_sweep.sh [loadgen binary] [out dir] [objects]
set -euo pipefail
loadgen=${1:-build/lg/loadgen/edgephys-loadgen}
out=${2:-ambient-sweep}
objects=${3:-1000}
mkdir -p "$out"
quarter=(--layers 1 --stirrer-reach 0.75 --stirrer-speed 1.0)
for hz in 12 8 6 4; do
  "$loadgen" multiobject --objects "$objects" --no-bench --duration 8 --ambient-hz "$hz" \
    "${quarter[@]}" --charts '' --no-progress --json "$out/quarter_$hz.json" >/dev/null
  "$loadgen" multiobject --objects "$objects" --no-bench --duration 8 --ambient-hz "$hz" \
    --charts '' --no-progress --json "$out/full_$hz.json" >/dev/null
done
python3 - "$out" <<'PY'
import json, sys
out = sys.argv[1]
print("scene,ambient_hz,egress_ratio_to_paper,moving_mean,moving_min,bytes_per_update,"
      "display_err_p50_mm,display_err_p99_mm,display_err_hermite_p99_mm,playout_delay_ms,err_vs_sent_max_mm")
for scene in ("quarter", "full"):
    with open(f"{out}/{scene}.dat", "w") as dat:
        for hz in (12, 8, 6, 4):
            r = json.load(open(f"{out}/{scene}_{hz}.json"))["results"][0]
            row = [r["egress_ratio_to_paper"], r["relay_moving_fraction"], r["relay_moving_fraction_min"],
                   r["bytes_per_update"], r["display_err_p50_m"] * 1e3, r["display_err_p99_m"] * 1e3,
                   r["display_err_hermite_p99_m"] * 1e3, r["display_delay_ms_median"],
                   r["pos_err_sent_max_m"] * 1e3]
            print(scene, hz, *(f"{x:.3f}" for x in row), sep=",")
            dat.write(f"{hz} {row[0]:.4f} {row[4]:.3f} {row[5]:.3f}\n")
PY
if command -v gnuplot >/dev/null; then
  for term in "pngcairo size 900,560:png" "svg size 900,560:svg"; do
    gnuplot <<GP
set terminal ${term%%:*}
set output '$out/ambient_tradeoff.${term##*:}'
set title 'Ambient rate: egress vs what a receiver displays ($objects boxes, 1 mm / 0.1 deg codec)'
set xlabel 'egress per client / paper Obj_$objects'
set ylabel 'display error vs truth (mm)'
set key top right
set grid
set termoption noenhanced
set arrow from 0.2, graph 0 to 0.2, graph 1 nohead dashtype 2
plot '$out/quarter.dat' using 2:4 with linespoints title 'quarter-plus moving: p99', \
     '' using 2:4:(sprintf('%d Hz', \$1)) with labels offset 1.5,0.6 notitle, \
     '$out/quarter.dat' using 2:3 with linespoints title 'quarter-plus moving: p50', \
     '$out/full.dat' using 2:4 with linespoints title 'full stir: p99', \
     '' using 2:4:(sprintf('%d Hz', \$1)) with labels offset 1.5,0.6 notitle, \
     '$out/full.dat' using 2:3 with linespoints title 'full stir: p50'
GP
  done
fi
