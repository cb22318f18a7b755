set terminal svg size 900,560
set output 'multiobject_egress.svg'
set title 'MultiObject: PhyS egress per client vs the paper (1 mm / 0.1 deg)'
set xlabel 'objects'
set ylabel 'Mb/s per client'
set logscale xy
set grid
set key top left
plot 'multiobject.dat' using 1:6 with linespoints lw 2 title 'edgephys (measured)', 'multiobject.dat' using 1:($7>0?$7:1/0) with linespoints pt 6 ps 1.5 title 'paper', 'multiobject.dat' using 1:($8>0?$8:1/0) with lines dt 2 title 'paper / 5 (target)'
