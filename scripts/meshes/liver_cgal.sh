#!/usr/bin/env bash
# Meshes SOFA's liver-smooth.obj with `stroma mesh surface` (CGAL Mesh_3) at three sizes: the
# ~2k and ~5k-element livers shipped in scenarios/meshes/ (in the OBJ's units, as liver.msh and
# liver_fine.msh; the physical scenes scale them by 0.025 to a 16 cm liver), and a ~15k one that
# is only timed (docs/MESHING.md). The OBJ has 7 self-intersecting triangle pairs: --repair.
# The shipped files (2,330 and 5,258 elements) were made on 2026-12-04, before `--tets` became
# an element count met by a size control and before the boundary fit: this script now makes
# ~1,800 and ~4,000 elements (the explicit facet distances bound the count from below).
# Usage: scripts/meshes/liver_cgal.sh [OUT_DIR]   (default scenarios/meshes)
set -euo pipefail
cd "$(dirname "$0")/../.."
out=${1:-scenarios/meshes}
obj=scenarios/meshes/liver-smooth.obj
build/stroma mesh surface "$obj" --repair --tets 1000 --facet-distance 0.03 --out "$out/liver_cgal_2k.msh" --no-png
build/stroma mesh surface "$obj" --repair --tets 4000 --facet-distance 0.02 --out "$out/liver_cgal_5k.msh" --no-png
if [ "$out" != scenarios/meshes ]; then
  build/stroma mesh surface "$obj" --repair --tets 12000 --out "$out/liver_cgal_15k.msh" --no-png
fi
