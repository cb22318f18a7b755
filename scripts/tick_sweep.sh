#!/usr/bin/env bash
# User-to-user latency against what it costs, as the relay's tick rate varies
# (docs/benchmarks.md, "The tail is the tick cadence"). For each tick rate, `repeat` ccu runs
# of 100 users in one room, the rates alternating within each round; prints CSV (medians over
# the runs) and charts p99 latency against relay CPU and egress. Bounded: rates x repeat runs
# of about 35 s each.
#   usage: scripts/tick_sweep.sh [loadgen binary] [out dir] [repeat] [rates...]
set -euo pipefail
loadgen=${1:-build/lg/loadgen/edgephys-loadgen}
out=${2:-tick-sweep}
repeat=${3:-3}
shift $(( $# < 3 ? $# : 3 ))
rates=("$@")
[ ${#rates[@]} -gt 0 ] || rates=(30 60 120 240)
mkdir -p "$out"
for ((i = 1; i <= repeat; ++i)); do
  for t in "${rates[@]}"; do
    "$loadgen" ccu --users 100 --ramp 8 --duration 12 --tick-rate "$t" --charts '' \
      --json "$out/tick${t}_$i.json" >/dev/null 2>&1
  done
done
python3 - "$out" "$repeat" "${rates[@]}" <<'PY'
import json, statistics, sys
out, repeat, rates = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
keys = ["latency_arrival_ms_p50", "latency_arrival_ms_p99", "latency_user_to_user_ms_p99",
        "grab_latency_ms_p99", "relay_cpu_mean", "egress_bytes_per_s_per_user", "hand_update_ratio",
        "reliable_lost"]
print("tick_hz," + ",".join(keys))
with open(f"{out}/tick.dat", "w") as dat:
    for t in rates:
        runs = [json.load(open(f"{out}/tick{t}_{i}.json"))["summary"] for i in range(1, repeat + 1)]
        med = [statistics.median(r[k] for r in runs) for k in keys]
        print(t + "," + ",".join(f"{m:.3f}" for m in med))
        dat.write(t + " " + " ".join(f"{m:.4f}" for m in med) + "\n")
PY
if command -v gnuplot >/dev/null; then
  for term in "pngcairo size 900,560:png" "svg size 900,560:svg"; do
    gnuplot <<GP
set terminal ${term%%:*}
set output '$out/tick_tradeoff.${term##*:}'
set termoption noenhanced
set title 'ccu 100 users, one room: latency p99 vs tick rate (medians of $repeat runs)'
set xlabel 'relay ticks per second'
set ylabel 'user-to-user p99 (ms)'
set y2label 'relay CPU (cores) / egress (x 100 kB/s per user)'
set y2tics
set ytics nomirror
set logscale x 2
set grid
set key top right
set arrow from graph 0, first 33.7 to graph 1, first 33.7 nohead dashtype 2
set label '2 x 16.7 ms + PhyS step' at graph 0.02, first 35
plot '$out/tick.dat' using 1:3 with linespoints title 'hand p99, socket', \
     '' using 1:4 with linespoints title 'hand p99, SDK', \
     '' using 1:5 with linespoints title 'grab p99, SDK', \
     '' using 1:6 axes x1y2 with linespoints title 'relay CPU', \
     '' using 1:(\$7/100000) axes x1y2 with linespoints title 'egress'
GP
  done
fi
