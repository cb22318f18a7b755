# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.
set terminal pngcairo size 800,450 noenhanced font 'sans,10'
set output 'interp_sweep.png'
set title "interp-sweep: display error against send rate (clean)"
set xlabel "send rate Hz"
set ylabel "position error p99 (mm)"
set grid
set key top left
set datafile missing '?'
set logscale y
plot 'interp_sweep.dat' index 0 using 1:2 with linespoints lw 2 title "lerp-slerp p99 mm", \
     'interp_sweep.dat' index 0 using 1:3 with linespoints lw 2 title "hermite p99 mm"
