# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.
set terminal pngcairo size 800,450 noenhanced font 'sans,10'
set output 'codec_sweep.png'
set title "codec-sweep: bandwidth against position error"
set xlabel "pos max mm"
set ylabel "KB/s per receiver"
set grid
set key top left
set datafile missing '?'
plot 'codec_sweep.dat' index 0 using 1:2 with linespoints lw 2 title "step, mm", \
     'codec_sweep.dat' index 1 using 1:2 with linespoints lw 2 title "rotation bound, deg", \
     'codec_sweep.dat' index 2 using 1:2 with linespoints lw 2 title "threshold, mm"
