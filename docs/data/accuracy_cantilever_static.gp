set terminal pngcairo size 1200,800 font 'DejaVu Sans,10'
set output 'docs/img/accuracy_cantilever_static.png'
set datafile separator ','
set logscale xy
set grid
set key top right
set title "Cantilever (refs/a): static tip deflection vs -1.4735e-3 m"
set xlabel "wall time to the answer (s): static solve; peers: the run to rest"
set ylabel 'relative error against the reference'
set format y '%.0e'
set xrange [0.0001:100]
set yrange [0.01:100]
set style textbox opaque noborder margins 1,1
$front << EOD
0.0007,0.4472,"1"
0.0032,0.2179,"2, 3"
0.0032,0.2179,""
0.0062,0.2178,"4"
0.0074,0.1604,"5"
0.013,0.1603,"6"
0.0154,0.1197,"7"
0.0261,0.1196,"8"
0.034,0.0803,"9"
0.0597,0.0802,"10"
EOD
plot 'docs/data/accuracy_cantilever_static.csv' skip 1 using (strcol(2) eq 'mesh x element (CHOLMOD)' && $11 == 1 ? $9 : NaN):7 with points pt 5 ps 1.4 title 'mesh x element (CHOLMOD)', \
'docs/data/accuracy_cantilever_static.csv' skip 1 using (strcol(2) eq 'CG tolerance (warped Cholesky PCG)' && $11 == 1 ? $9 : NaN):7 with points pt 7 ps 1.4 title 'CG tolerance (warped Cholesky PCG)', \
'docs/data/accuracy_cantilever_static.csv' skip 1 using (strcol(2) eq 'stable neo-Hookean (CHOLMOD)' && $11 == 1 ? $9 : NaN):7 with points pt 9 ps 1.4 title 'stable neo-Hookean (CHOLMOD)', \
'docs/data/accuracy_cantilever_static.csv' skip 1 using (strcol(2) eq 'Bullet FEM (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 11 ps 1.4 title 'Bullet FEM (peer)', \
'docs/data/accuracy_cantilever_static.csv' skip 1 using (strcol(2) eq 'Bullet FEM neo-Hookean (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 13 ps 1.4 title 'Bullet FEM neo-Hookean (peer)', \
'docs/data/accuracy_cantilever_static.csv' skip 1 using (strcol(2) eq 'Bullet FEM neo-Hookean matched (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 15 ps 1.4 title 'Bullet FEM neo-Hookean matched (peer)', \
'docs/data/accuracy_cantilever_static.csv' skip 1 using (strcol(2) eq 'Bullet soft body (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 17 ps 1.4 title 'Bullet soft body (peer)', \
$front using 1:2 with lines lw 2 lc rgb '#444444' title 'Pareto front', \
$front using 1:2:3 with labels boxed right font ',10' offset char -0.7,-0.9 notitle
