# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.
set terminal pngcairo size 800,450 noenhanced font 'sans,10'
set output 'relay_compare.png'
set title "relay-compare: egress per receiver"
set xlabel "objects"
set ylabel "KB/s per receiver"
set grid
set key top left
set datafile missing '?'
set logscale x 2
set logscale y
plot 'relay_compare.dat' index 0 using 1:2 with linespoints lw 2 title "photon", \
     'relay_compare.dat' index 1 using 1:2 with linespoints lw 2 title "paper", \
     'relay_compare.dat' index 2 using 1:2 with linespoints lw 2 title "edgephys"
