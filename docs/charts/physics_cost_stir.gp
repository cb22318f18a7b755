# Sessions 11 and 12 (docs/benchmarks.md, "Full stir, session 11" and "session 12"): physics_cost_report's chart over
# physics_cost_stir.dat, whose rows come from the runs named in their labels; run in docs/charts.
do for [fmt in "png svg"] {
  if (fmt eq "png") { set terminal pngcairo size 900,520 font "sans,9" noenhanced } else { set terminal svg size 900,520 font "sans,9" noenhanced }
  set output "physics_cost_stir.".fmt
  set title "PhyS settings, full stir (2,000 boxes, after 10 s), sessions 11-12: step time vs accuracy (the suite at each setting)"

  set xlabel "PhyS step CPU time / raw Bullet at its defaults (same run, medians)"
  set ylabel "never-sleeping ten-box stack: drift over 60 s (m, log)"
  set logscale y
  set yrange [0.005:30]
  set xrange [0.45:1.0]
  set grid
  set key bottom center
  set arrow from 0.5, graph 0 to 0.5, graph 1 nohead dt 2 lc rgb "#888888"
  set label "target 0.5x" at 0.505, graph 0.95 left font "sans,8"
  set arrow from graph 0, first 0.25 to graph 1, first 0.25 nohead dt 2 lc rgb "#888888"
  set label "suite bound 0.25 m" at graph 0.3, first 0.3 left font "sans,8"
  plot "physics_cost_stir.dat" using 3:($7 == 1 ? $11 : 1/0) with points pt 7 ps 1.3 lc rgb "#1f77b4" title "accuracy suite passes", \
       "physics_cost_stir.dat" using 3:($7 == 0 ? $11 : 1/0) with points pt 2 ps 1.6 lc rgb "#d62728" title "suite fails", \
       "physics_cost_stir.dat" using 3:($13 > 0 ? $11 : 1/0) with points pt 6 ps 2.4 lc rgb "#ff7f0e" title "boxes escaped the container", \
       "physics_cost_stir.dat" using 3:11:2 with labels offset 0.5,0.5 left font "sans,7" rotate by 20 notitle
  unset multiplot
  set output
  reset
}
