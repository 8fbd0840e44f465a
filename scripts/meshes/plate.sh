#!/usr/bin/env bash
# Builds scenarios/meshes/plate_60x60x2mm.msh: a thin square plate, 60 x 60 x 2 mm in metres,
# meshed by gmsh (OpenCASCADE box, Delaunay, element size 1.5 mm: 4,030 nodes, 12,084
# tetrahedra, two to three elements through the thickness). The untuned thin-plate scene
# (scenarios/untuned/plate_2mm_50kpa.yaml) clamps its rim.
# Usage: scripts/meshes/plate.sh [OUT]   Needs: gmsh (scripts/setup.sh installs it).
set -euo pipefail
cd "$(dirname "$0")/../.."
out=${1:-scenarios/meshes/plate_60x60x2mm.msh}
geo=$(mktemp --suffix .geo)
trap 'rm -f "$geo"' EXIT
cat > "$geo" <<'GEO'
SetFactory("OpenCASCADE");
Box(1) = {0, 0, 0, 0.06, 0.06, 0.002};
Mesh.CharacteristicLengthMin = 0.0015;
Mesh.CharacteristicLengthMax = 0.0015;
Mesh.Algorithm3D = 1;
Mesh.Optimize = 1;
Physical Volume("plate") = {1};
GEO
gmsh "$geo" -3 -format msh22 -o "$out" > /dev/null
echo "wrote $out"
