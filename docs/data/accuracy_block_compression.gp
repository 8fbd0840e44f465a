set terminal pngcairo size 1200,800 font 'DejaVu Sans,10'
set output 'docs/img/accuracy_block_compression.png'
set datafile separator ','
set logscale xy
set grid
set key top right
set title "Bonded block, nu 0.49, pressed 1 % (refs/c): top force vs 0.3049 N"
set xlabel "wall time to the answer (s): static solve; peers: the run to rest"
set ylabel 'relative error against the reference'
set format y '%.0e'
set xrange [0.0001:100]
set yrange [0.01:1]
set style textbox opaque noborder margins 1,1
$front << EOD
0.001,0.361,"2"
0.002,0.2476,"3"
0.008,0.1372,"4"
0.14,0.1331,"5"
0.166,0.0921,"6"
0.771,0.0881,"7"
EOD
plot 'docs/data/accuracy_block_compression.csv' skip 1 using (strcol(2) eq 'mesh x element (CHOLMOD)' && $11 == 1 ? $9 : NaN):7 with points pt 5 ps 1.4 title 'mesh x element (CHOLMOD)', \
'docs/data/accuracy_block_compression.csv' skip 1 using (strcol(2) eq 'mesh x element (CG 1e-8)' && $11 == 1 ? $9 : NaN):7 with points pt 7 ps 1.4 title 'mesh x element (CG 1e-8)', \
'docs/data/accuracy_block_compression.csv' skip 1 using (strcol(2) eq 'CG tolerance (warped Cholesky PCG' && $11 == 1 ? $9 : NaN):7 with points pt 9 ps 1.4 title 'CG tolerance (warped Cholesky PCG, h 3.333 mm)', \
'docs/data/accuracy_block_compression.csv' skip 1 using (strcol(2) eq 'Bullet FEM (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 11 ps 1.4 title 'Bullet FEM (peer)', \
$front using 1:2 with lines lw 2 lc rgb '#444444' title 'Pareto front', \
$front using 1:2:3 with labels boxed right font ',10' offset char -0.7,-0.9 notitle
