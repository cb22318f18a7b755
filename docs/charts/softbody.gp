# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.
set terminal pngcairo size 800,450 noenhanced font 'sans,10'
set output 'softbody.png'
set title "softbody: egress per receiver against the paper"
set xlabel "bunnies"
set ylabel "Mb/s per receiver (UDP payload, sealed)"
set grid
set key top left
set datafile missing '?'
plot 'softbody.dat' index 0 using 1:2 with linespoints lw 2 title "Mb/s per receiver (UDP payload, sealed)", \
     'softbody.dat' index 0 using 1:3 with linespoints lw 2 title "paper Mb/s"
