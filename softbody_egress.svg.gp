set terminal svg size 900,560
set output 'softbody_egress.svg'
set title 'Soft bodies: PhyS egress per client vs the paper (1 mm particle step)'
set xlabel 'bunnies (~500 particles each)'
set ylabel 'Mb/s per client'
set grid
set key top left
set style data histograms
set style histogram clustered gap 1
set style fill solid 0.7 border -1
set yrange [0:*]
plot 'softbody.dat' using 2:xtic(1) title 'edgephys (measured)', 'softbody.dat' using ($3>0?$3:1/0):xtic(1) title 'paper'
