set terminal svg size 900,560
set output 'multiobject_error.svg'
set title 'MultiObject: receiver position error'
set xlabel 'objects'
set ylabel 'mm'
set logscale x
set grid
set key top left
plot 'multiobject.dat' using 1:9 with linespoints title 'max vs relay state, same moment', 'multiobject.dat' using 1:10 with linespoints title 'p99 vs relay state, same moment', 'multiobject.dat' using 1:11 with linespoints title 'max vs the relay state sent'
