#!/usr/bin/env python3
"""Builds scenarios/meshes/liver_fine.msh: a 2-5k-tet liver from SOFA's liver-smooth.obj.

SOFA's smooth liver surface has a small fold: 16 pairs of its triangles intersect (TetGen -d finds
them, around vertices 385-387, 833-838, 1536-1538 and 2031), so no mesher accepts it as it is.
This script
  1. asks TetGen (-d) which triangles intersect,
  2. smooths only their vertices and 1-ring (three half-weighted Laplacian passes), and repeats
     until TetGen finds no intersection (one round today: 24 vertices move, at most 1.24 mm in the
     mesh's centimetres, i.e. 0.12 units of a 6.4-unit-long surface),
  3. hands the repaired surface to gmsh (ClassifySurfaces, CreateGeometry, Delaunay + optimiser)
     with a uniform element size (--size, mesh units; 0.45 gives about 4,000 tetrahedra).
Nothing here is a mesher: TetGen checks, gmsh meshes.

Usage: scripts/meshes/liver_fine.py [--size 0.45] [--out scenarios/meshes/liver_fine.msh]
Needs: tetgen, gmsh (Debian packages; scripts/setup.sh installs both).
"""
import argparse, os, re, subprocess, sys, tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def read_obj(path):
    v, f = [], []
    for line in open(path):
        p = line.split()
        if p and p[0] == "v":
            v.append([float(x) for x in p[1:4]])
        elif p and p[0] == "f":
            f.append([int(x.split("/")[0]) - 1 for x in p[1:]])
    return v, f


def intersecting_vertices(v, f, work):
    path = os.path.join(work, "surface.smesh")
    with open(path, "w") as o:
        o.write(f"{len(v)} 3 0 0\n")
        for i, x in enumerate(v):
            o.write(f"{i + 1} {x[0]!r} {x[1]!r} {x[2]!r}\n")
        o.write(f"{len(f)} 0\n")
        for t in f:
            o.write(f"3 {t[0] + 1} {t[1] + 1} {t[2] + 1}\n")
        o.write("0\n0\n")
    out = subprocess.run(["tetgen", "-d", path], capture_output=True, text=True, check=True).stdout
    bad = set()
    for m in re.finditer(r"\(\s*(\d+),\s*(\d+),\s*(\d+)\)", out):
        bad.update(int(x) - 1 for x in m.groups())
    return bad


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--surface", default=os.path.join(ROOT, "scenarios", "meshes", "liver-smooth.obj"))
    ap.add_argument("--size", type=float, default=0.45, help="element size in mesh units")
    ap.add_argument("--out", default=os.path.join(ROOT, "scenarios", "meshes", "liver_fine.msh"))
    a = ap.parse_args()
    v, f = read_obj(a.surface)
    orig = [list(x) for x in v]
    ring = [set() for _ in v]
    for t in f:
        for i in t:
            ring[i].update(j for j in t if j != i)
    with tempfile.TemporaryDirectory() as work:
        for round_ in range(20):
            bad = intersecting_vertices(v, f, work)
            print(f"liver_fine: round {round_}: {len(bad)} vertices on intersecting triangles", flush=True)
            if not bad:
                break
            region = set(bad)
            for b in bad:
                region |= ring[b]
            for _ in range(3):
                mean = {i: [sum(v[j][k] for j in ring[i]) / len(ring[i]) for k in range(3)] for i in region}
                for i, x in mean.items():
                    v[i] = [0.5 * v[i][k] + 0.5 * x[k] for k in range(3)]
        else:
            sys.exit("liver_fine: the surface still intersects itself after 20 rounds")
        moved = [sum((a_ - b_) ** 2 for a_, b_ in zip(x, y)) ** 0.5 for x, y in zip(v, orig)]
        print(f"liver_fine: {sum(1 for d in moved if d > 0)} vertices moved, at most {max(moved):.4f} units")
        stl = os.path.join(work, "liver.stl")
        with open(stl, "w") as o:
            o.write("solid liver\n")
            for t in f:
                o.write(" facet normal 0 0 0\n  outer loop\n")
                for i in t:
                    o.write(f"   vertex {v[i][0]!r} {v[i][1]!r} {v[i][2]!r}\n")
                o.write("  endloop\n endfacet\n")
            o.write("endsolid liver\n")
        geo = os.path.join(work, "liver.geo")
        with open(geo, "w") as o:
            o.write(f'Merge "{stl}";\nClassifySurfaces{{40*Pi/180, 1, 1, Pi}};\nCreateGeometry;\n'
                    "Surface Loop(1) = Surface{:};\nVolume(1) = {1};\nPhysical Volume(1) = {1};\n"
                    f"Mesh.CharacteristicLengthMax = {a.size};\nMesh.CharacteristicLengthMin = {a.size};\n"
                    "Mesh.Optimize = 1;\nMesh.MshFileVersion = 2.2;\nGeneral.NumThreads = 1;\nMesh.RandomSeed = 1;\n")
        subprocess.run(["gmsh", "-3", geo, "-o", a.out, "-v", "2"], check=True)
    print(f"liver_fine: wrote {a.out}")


if __name__ == "__main__":
    main()
