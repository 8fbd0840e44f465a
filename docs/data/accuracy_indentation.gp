set terminal pngcairo size 1200,800 font 'DejaVu Sans,10'
set output 'docs/img/accuracy_indentation.png'
set datafile separator ','
set logscale xy
set grid
set key top right
set title "Sphere indentation (refs/e): force at 1 mm vs 0.019604 N"
set xlabel "wall time to the answer (s): static solve; peers: the run to rest"
set ylabel 'relative error against the reference'
set format y '%.0e'
set xrange [0.1:10000]
set yrange [0.001:1]
set style textbox opaque noborder margins 1,1
$front << EOD
0.327,0.2556,"1"
1.148,0.1312,"2"
1.291,0.0628,"3"
2.76,0.0623,"4"
3.377,0.0018,"5"
EOD
plot 'docs/data/accuracy_indentation.csv' skip 1 using (strcol(2) eq 'mesh grading (linear' && $11 == 1 ? $9 : NaN):7 with points pt 5 ps 1.4 title 'mesh grading (linear, penalty 1e9)', \
'docs/data/accuracy_indentation.csv' skip 1 using (strcol(2) eq 'penalty stiffness (first cell 0.2 mm)' && $11 == 1 ? $9 : NaN):7 with points pt 7 ps 1.4 title 'penalty stiffness (first cell 0.2 mm)', \
'docs/data/accuracy_indentation.csv' skip 1 using (strcol(2) eq 'element model (first cell 0.2 mm)' && $11 == 1 ? $9 : NaN):7 with points pt 9 ps 1.4 title 'element model (first cell 0.2 mm)', \
'docs/data/accuracy_indentation.csv' skip 1 using (strcol(2) eq 'Bullet FEM (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 11 ps 1.4 title 'Bullet FEM (peer)', \
$front using 1:2 with lines lw 2 lc rgb '#444444' title 'Pareto front', \
$front using 1:2:3 with labels boxed right font ',10' offset char -0.7,-0.9 notitle
