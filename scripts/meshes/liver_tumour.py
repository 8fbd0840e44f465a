#!/usr/bin/env python3
"""Builds scenarios/meshes/liver_tumour.msh: the fine liver (liver_fine.msh, 3,876 tetrahedra)
with two gmsh physical volumes — 1 "liver" and 2 "tumour", the tetrahedra whose centroid lies
within --radius of --centre (mesh units; the defaults put a 22 mm sphere 25 mm under the upper
surface of the 16 cm liver, below the press point of trajectories/physical_liver_press.yaml, once
scaled by 0.025). A scenario gives the tumour its own material (docs/TISSUE.md):
scenarios/physical/liver_16cm_tumour.yaml. Nothing is re-meshed: the tumour is the tetrahedra it
contains, so its surface is jagged at the element size (an image mesher's labelled output —
issue 19 — is the smooth way).

Usage: scripts/meshes/liver_tumour.py [--centre X Y Z] [--radius R] [--out PATH]
"""
import argparse, os

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("--centre", nargs=3, type=float, default=[-1.5, 3.8, 0.5])
ap.add_argument("--radius", type=float, default=0.88)
ap.add_argument("--out", default=os.path.join(ROOT, "scenarios/meshes/liver_tumour.msh"))
args = ap.parse_args()

lines = open(os.path.join(ROOT, "scenarios/meshes/liver_fine.msh")).read().split("\n")
i = lines.index("$Nodes")
n = int(lines[i + 1])
nodes = {}
for l in lines[i + 2:i + 2 + n]:
    t = l.split()
    nodes[t[0]] = [float(v) for v in t[1:4]]
j = lines.index("$Elements")
m = int(lines[j + 1])
out_elems, tumour = [], 0
for l in lines[j + 2:j + 2 + m]:
    t = l.split()
    if t[1] != "4":
        continue
    ntags = int(t[2])
    tet = t[3 + ntags:]
    c = [sum(nodes[v][k] for v in tet) / 4 for k in range(3)]
    inside = sum((c[k] - args.centre[k]) ** 2 for k in range(3)) < args.radius ** 2
    tag = 2 if inside else 1
    tumour += inside
    out_elems.append(f"{len(out_elems) + 1} 4 2 {tag} {tag} " + " ".join(tet))
with open(args.out, "w") as f:
    f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
    f.write('$PhysicalNames\n2\n3 1 "liver"\n3 2 "tumour"\n$EndPhysicalNames\n')
    f.write("\n".join(lines[i:i + 2 + n]) + "\n$EndNodes\n")
    f.write(f"$Elements\n{len(out_elems)}\n" + "\n".join(out_elems) + "\n$EndElements\n")
print(f"{args.out}: {len(out_elems)} tetrahedra, {tumour} in the tumour")
