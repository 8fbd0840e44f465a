#!/bin/sh
# The needle's force–depth curve (docs/NEEDLE.md): runs scenarios/needle_insertion.yaml and plots
# the force the grasper feels against the tip's depth below the block's top, beside the model of
# Okamura, Simone & O'Leary (2004) with the scenario's parameters. Needs gnuplot (scripts/setup.sh).
#   scripts/plot_needle_force.sh [OUT.png]   (default docs/img/needle_force.png)
set -eu
here=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$here/docs/img/needle_force.png}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$here/build/stroma" run "$here/scenarios/needle_insertion.yaml" --quiet --out "$work/run" > /dev/null
# time, force felt (N), tip depth (mm: the tip is 20 mm below the centre of mass; the top at 50 mm),
# going in (1) or out (0), the model's force from the inserted length (N)
python3 - "$work/run/metrics.csv" > "$work/curve.dat" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
for a, b in zip(rows, rows[1:]):
    depth = 1e3 * (0.05 - (float(a["needle_y"]) - 0.02))
    going_in = float(b["needle_y"]) < float(a["needle_y"]) - 1e-9
    going_out = float(b["needle_y"]) > float(a["needle_y"]) + 1e-9
    if going_in or going_out:
        length = float(a["needle_inserted_length"])
        model = (0.15 + 3.0 * length if going_in else -3.0 * length) if a["needle_phase"] != "outside" else float("nan")
        print(a["time"], a["grasper_fy"], depth, 1 if going_in else 0, model)
PY
gnuplot <<GP
set terminal pngcairo size 900,520 font ",11" noenhanced
set output "$out"
set title "Needle insertion and withdrawal at 10 mm/s (scenarios/needle_insertion.yaml)"
set xlabel "tip depth below the surface (mm)"
set ylabel "force felt by the grasper (N)"
set grid
set key right center
set arrow from graph 0, first 0.3 to graph 1, first 0.3 nohead dt 3 lc rgb "#888888"
set label "puncture force 0.3 N" at 14, 0.315 textcolor rgb "#666666"
plot "$work/curve.dat" using 3:(\$4 == 1 ? \$2 : 1/0) with lines lw 2 lc rgb "#c0392b" title "insertion (Stroma)", \
     "$work/curve.dat" using 3:(\$4 == 0 ? \$2 : 1/0) with lines lw 2 lc rgb "#2471a3" title "withdrawal (Stroma)", \
     "$work/curve.dat" using 3:(\$4 == 1 ? \$5 : 1/0) with lines dt 2 lw 1.5 lc rgb "black" title "model: cutting 0.15 N + 3 N/m x inserted length", \
     "$work/curve.dat" using 3:(\$4 == 0 ? \$5 : 1/0) with lines dt 4 lw 1.5 lc rgb "black" title "model: -3 N/m x inserted length (withdrawal)"
GP
echo "wrote $out"
