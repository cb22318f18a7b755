set terminal pngcairo size 900,480
set output 'isolation_session9.png'
set title "isolation (session 9): room A's hand p99 at the socket per 0.5 s, B (or the burner) from t = 14 s"
set xlabel 'time (s)'; set ylabel 'A socket p99 (ms)'; set grid; set key top left box opaque
set arrow from 14, graph 0 to 14, graph 1 nohead dashtype 2
set yrange [0:110]
plot 'isolation_session9_before.dat' using 1:3 with lines lw 2 title 'previous relay (2.03x)', \
     'isolation_session9_best.dat' using 1:3 with lines lw 2 title 'this relay, B thread nice 19 (1.30x)', \
     'isolation_session9_burn.dat' using 1:3 with lines lw 2 title 'control: physics-burn process, no B (1.09x)'
