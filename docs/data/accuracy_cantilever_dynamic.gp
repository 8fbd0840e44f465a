set terminal pngcairo size 1200,800 font 'DejaVu Sans,10'
set output 'docs/img/accuracy_cantilever_dynamic.png'
set datafile separator ','
set logscale xy
set grid
set key top right
set title "Cantilever (refs/d): first frequency from the released tip vs 16.100 Hz"
set xlabel "wall seconds per simulated second"
set ylabel 'relative error against the reference'
set format y '%.0e'
set xrange [0.01:100]
set yrange [0.001:1]
set style textbox opaque noborder margins 1,1
$front << EOD
0.077,0.1778,"1"
0.34,0.0256,"2"
0.5,0.0027,"3"
EOD
plot 'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'mesh x dt (implicit Euler)' && $11 == 1 ? $9 : NaN):7 with points pt 5 ps 1.4 title 'mesh x dt (implicit Euler)', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'CG tolerance (Jacobi)' && $11 == 1 ? $9 : NaN):7 with points pt 7 ps 1.4 title 'CG tolerance (Jacobi)', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'CG iteration cap (Jacobi)' && $11 == 1 ? $9 : NaN):7 with points pt 9 ps 1.4 title 'CG iteration cap (Jacobi)', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'warm start (Jacobi CG 1e-6)' && $11 == 1 ? $9 : NaN):7 with points pt 11 ps 1.4 title 'warm start (Jacobi CG 1e-6)', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'element model' && $11 == 1 ? $9 : NaN):7 with points pt 13 ps 1.4 title 'element model', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'symplectic Euler (largest stable dt)' && $11 == 1 ? $9 : NaN):7 with points pt 15 ps 1.4 title 'symplectic Euler (largest stable dt)', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'Bullet FEM (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 17 ps 1.4 title 'Bullet FEM (peer)', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'Bullet FEM neo-Hookean (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 19 ps 1.4 title 'Bullet FEM neo-Hookean (peer)', \
'docs/data/accuracy_cantilever_dynamic.csv' skip 1 using (strcol(2) eq 'Bullet FEM neo-Hookean matched (peer)' && $11 == 1 ? $9 : NaN):7 with points pt 21 ps 1.4 title 'Bullet FEM neo-Hookean matched (peer)', \
$front using 1:2 with lines lw 2 lc rgb '#444444' title 'Pareto front', \
$front using 1:2:3 with labels boxed right font ',10' offset char -0.7,-0.9 notitle
