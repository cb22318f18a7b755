# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.
set terminal pngcairo size 800,450 noenhanced font 'sans,10'
set output 'ceiling.png'
set title "ceiling: relay datagrams/s over iperf3's"
set xlabel "io threads"
set ylabel "relay / iperf3 datagrams per second"
set grid
set key top left
set datafile missing '?'
plot 'ceiling.dat' index 0 using 2:xtic(1) with linespoints lw 2 title "ratio to iperf3"
