# Written by scripts/bench/figures.py from docs/charts/figures.json; do not edit.
set terminal pngcairo size 800,450 noenhanced font 'sans,10'
set output 'multiobject_full.png'
set title "multiobject full stir: step time, PhyS and raw Bullet"
set xlabel "boxes"
set ylabel "step (ms)"
set grid
set key top left
set datafile missing '?'
plot 'multiobject_full.dat' index 0 using 1:2 with linespoints lw 2 title "PhyS step ms", \
     'multiobject_full.dat' index 0 using 1:3 with linespoints lw 2 title "raw Bullet step ms"
