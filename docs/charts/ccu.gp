# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.
set terminal pngcairo size 800,450 noenhanced font 'sans,10'
set output 'ccu.png'
set title "ccu: hand latency at the receiving socket"
set xlabel "users"
set ylabel "hand latency (ms)"
set grid
set key top left
set datafile missing '?'
plot 'ccu.dat' index 0 using 1:2 with linespoints lw 2 title "0.0 socket p50 ms", \
     'ccu.dat' index 0 using 1:3 with linespoints lw 2 title "0.0 socket p99 ms", \
     'ccu.dat' index 1 using 1:2 with linespoints lw 2 title "10.0 socket p50 ms", \
     'ccu.dat' index 1 using 1:3 with linespoints lw 2 title "10.0 socket p99 ms"
