# gnuplot docs/charts/key_samples_tradeoff.gp (from the repository root): egress against display
# error p99 for the fixed ambient rate, velocities (format 12) and key samples, quarter-plus and
# full-stir scenes, 1,000 boxes (docs/benchmarks.md, "Key samples", session 8). Left: the truth as
# it reached the relay (the earlier tables' yardstick); right: the truth at the time PhyS computed
# it for (no format-12 figures measured that way). Labelled: medians of 3 (m). Session 9 adds key
# samples coded as format 13 (docs/benchmarks.md, "Key samples, coded") and the issue's two
# targets per scene (T1: p99 3x lower at today's egress; T2: half today's egress at today's p99;
# arrival yardstick on the left, state yardstick on the right). Session 11 ("Display error, session
# 11") adds the fixed rate stamped with state_time, key samples stamped with the relay's mean PhyS
# lag (A) and at the kink (format 14, K), and moves the targets to that sitting's fixed 6 Hz
# medians. Data: key_samples_tradeoff.dat.
d = 'docs/charts/key_samples_tradeoff.dat'
do for [t in 'png svg'] {
  if (t eq 'png') { set terminal pngcairo size 1300,560 font ',9' } else { set terminal svg size 1300,560 font ',9' }
  set output 'docs/charts/key_samples_tradeoff.'.t
  set termoption noenhanced
  set multiplot layout 1,2 title 'Egress vs what a receiver displays, 1,000 boxes: fixed ambient rate, velocities (format 12), key samples (format 2; 13; session 11: arrival-stamped A, at the kink K)'
  set grid
  set logscale x
  set xrange [0.06:2.2]
  set yrange [0:95]
  set xlabel 'egress per client / paper Obj_1000'
  set key top right font ',8'
  do for [col in '2 3'] {
    c = col + 0
    set ylabel (c == 2 ? 'display p99 (mm), truth as it reached the relay' : 'display p99 (mm), truth at the time PhyS computed it for')
    plot d index 0 using 1:c with linespoints pt 7 lc rgb '#1f77b4' title 'quarter-plus, fixed Hz (6 Hz: today)', \
         '' index 0 using 1:c:4 with labels font ',7' offset 0,0.9 notitle, \
         '' index 1 using 1:c with linespoints pt 5 lc rgb '#9467bd' title 'quarter-plus, format 12', \
         '' index 2 using 1:c with points pt 9 lc rgb '#2ca02c' title 'quarter-plus, key samples', \
         '' index 2 using 1:c:(strstrt(strcol(4),'(m)') ? strcol(4) : '') with labels font ',7' offset 0,-0.9 tc rgb '#2ca02c' notitle, \
         '' index 3 using 1:c with linespoints pt 7 lc rgb '#d62728' title 'full stir, fixed Hz (6 Hz: today)', \
         '' index 3 using 1:c:4 with labels font ',7' offset 0,0.9 notitle, \
         '' index 4 using 1:c with linespoints pt 5 lc rgb '#e377c2' title 'full stir, format 12', \
         '' index 5 using 1:c with points pt 11 lc rgb '#ff7f0e' title 'full stir, key samples', \
         '' index 5 using 1:c:(strstrt(strcol(4),'(m)') ? strcol(4) : '') with labels font ',7' offset 0,-0.9 tc rgb '#ff7f0e' notitle, \
         '' index 6 using 1:c with points pt 13 ps 1.2 lc rgb '#006400' title 'quarter-plus, key samples, format 13', \
         '' index 6 using 1:c:(strstrt(strcol(4),'(m)') ? strcol(4) : '') with labels font ',7' offset 0,-0.9 tc rgb '#006400' notitle, \
         '' index 7 using 1:c with points pt 15 ps 1.2 lc rgb '#8b4513' title 'full stir, key samples, format 13', \
         '' index 7 using 1:c:(strstrt(strcol(4),'(m)') ? strcol(4) : '') with labels font ',7' offset 0,-0.9 tc rgb '#8b4513' notitle, \
         '' index 9 using 1:c with points pt 6 ps 1.6 lw 2 lc rgb '#00bfbf' title 'quarter-plus, session 11', \
         '' index 9 using 1:c:(strstrt(strcol(4),'(m)') ? strcol(4) : '') with labels font ',7' offset 0,0.9 tc rgb '#008080' notitle, \
         '' index 10 using 1:c with points pt 4 ps 1.6 lw 2 lc rgb '#b8860b' title 'full stir, session 11', \
         '' index 10 using 1:c:(strstrt(strcol(4),'(m)') ? strcol(4) : '') with labels font ',7' offset 0,0.9 tc rgb '#8b6508' notitle, \
         '' index 8 using 1:c with points pt 3 ps 2 lc rgb '#000000' title 'targets (T1, T2 per scene; session 11 sitting)', \
         '' index 8 using 1:c:4 with labels font ',7' offset 1.2,0.6 notitle
  }
  unset multiplot
}
