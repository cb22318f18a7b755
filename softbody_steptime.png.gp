set terminal pngcairo size 900,560
set output 'softbody_steptime.png'
set title 'Soft bodies: PhyS step time'
set xlabel 'bunnies (~500 particles each)'
set ylabel 'ms per step'
set grid
set key top left
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.7 border -1
set yrange [0:*]
plot 'softbody.dat' using 4:xtic(1) title 'median (standalone)', 'softbody.dat' using 5:xtic(1) title 'p99 (standalone)', 'softbody.dat' using 6:xtic(1) title 'relay mean'
