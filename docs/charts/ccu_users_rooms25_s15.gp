# gnuplot docs/charts/ccu_users_rooms25_s15.gp (from the repository root): the ccu users sweep
# in rooms of 25, format 9, relay as its own process (docs/benchmarks.md, issue 11, session 15).
set terminal pngcairo size 900,450 font ',10'
set output 'docs/charts/ccu_users_rooms25_s15.png'
set multiplot layout 1,2 title 'ccu, rooms of 25, format 9 (default), relay as its own process, 2 shared vCPUs (session 15)'
set grid
set xlabel 'users'
set xrange [400:1100]
set logscale y
set yrange [5:1000]
set ylabel 'hand latency (ms)'
set key top left
plot 'docs/charts/ccu_users_rooms25_s15.dat' using 1:2 with linespoints title 'socket p50', \
     '' using 1:3 with linespoints title 'socket p99', \
     '' using 1:6 with linespoints title 'SDK p99', \
     50 with lines dashtype 2 title 'target p99 50 ms'
unset logscale y
set yrange [0:1.1]
set ylabel 'relay CPU (cores) / hand poses delivered'
set key bottom right
plot 'docs/charts/ccu_users_rooms25_s15.dat' using 1:4 with linespoints title 'relay CPU', \
     '' using 1:5 with linespoints title 'delivered', \
     0.9 with lines dashtype 2 title 'target delivered 0.9'
unset multiplot
