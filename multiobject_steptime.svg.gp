set terminal svg size 900,560
set output 'multiobject_steptime.svg'
set title 'MultiObject: PhyS step time vs raw Bullet (same scene, same run)'
set xlabel 'objects'
set ylabel 'ms per step'
set logscale xy
set grid
set key top left
plot 'multiobject.dat' using 1:2 with linespoints lw 2 title 'PhyS median', 'multiobject.dat' using 1:3 with linespoints dt 2 title 'PhyS p99', 'multiobject.dat' using 1:4 with linespoints lw 2 title 'raw Bullet median', 'multiobject.dat' using 1:5 with linespoints dt 2 title 'raw Bullet p99', 16.667 with lines lc rgb 'gray' title '60 Hz budget (16.7 ms)'
