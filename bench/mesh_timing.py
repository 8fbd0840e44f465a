#!/usr/bin/python3
"""Times `stroma mesh` and collects its quality reports into the table of docs/MESHING.md.

Cases: the phantoms of tests/data/images (ellipsoid + spherical inclusion, 1 mm and
0.8 x 0.8 x 2 mm voxels), a closed sphere and torus (written here as OBJ), SOFA's liver at three
sizes (scripts/meshes/liver_cgal.sh's settings), a torus phantom image (84 x 84 x 24 mm, tube
radius 12 mm, a 5 mm inclusion, 0.5 mm voxels: the case of issue 41 section 8) at the default
and at --size 1.5 mm, and a 256^3 label volume (0.5 mm voxels: an ellipsoid of semi-axes 60, 45,
35 mm with a 15 mm inclusion) at the default and at --size 1 mm. The images need python3-numpy. Each case runs `--runs` times (default 3); the table gives the median wall time
and the last run's report. Run from the repository root after scripts/build.sh:

    /usr/bin/python3 bench/mesh_timing.py [--runs 3] [--out out/mesh_timing] [--skip-256] [--only TEXT]
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time


def sphere_obj(path, R=0.05, nu=96, nv=48):
    v = [(0, 0, R)]
    for i in range(1, nv):
        th = math.pi * i / nv
        for j in range(nu):
            ph = 2 * math.pi * j / nu
            v.append((R * math.sin(th) * math.cos(ph), R * math.sin(th) * math.sin(ph), R * math.cos(th)))
    v.append((0, 0, -R))
    f = [(0, 1 + j, 1 + (j + 1) % nu) for j in range(nu)]
    for i in range(nv - 2):
        for j in range(nu):
            a, b = 1 + i * nu + j, 1 + i * nu + (j + 1) % nu
            f += [(a, a + nu, b + nu), (a, b + nu, b)]
    last, base = len(v) - 1, 1 + (nv - 2) * nu
    f += [(base + j, last, base + (j + 1) % nu) for j in range(nu)]
    write_obj(path, v, f)


def torus_obj(path, R=0.04, r=0.015, nu=96, nv=48):
    v = []
    for i in range(nu):
        for j in range(nv):
            u, w = 2 * math.pi * i / nu, 2 * math.pi * j / nv
            v.append(((R + r * math.cos(w)) * math.cos(u), (R + r * math.cos(w)) * math.sin(u), r * math.sin(w)))
    f = []
    for i in range(nu):
        for j in range(nv):
            a, b = i * nv + j, ((i + 1) % nu) * nv + j
            c, d = ((i + 1) % nu) * nv + (j + 1) % nv, i * nv + (j + 1) % nv
            f += [(a, b, c), (a, c, d)]
    write_obj(path, v, f)


def write_obj(path, v, f):
    with open(path, "w") as o:
        for p in v:
            o.write("v %.12g %.12g %.12g\n" % p)
        for t in f:
            o.write("f %d %d %d\n" % (t[0] + 1, t[1] + 1, t[2] + 1))


def write_nifti_labels(path, lab, spacing, origin):
    """A uint8 label volume as NIfTI-1 (.nii.gz), axis-aligned, millimetres; no nibabel needed."""
    import gzip
    import struct
    hdr = bytearray(348)
    struct.pack_into("<i", hdr, 0, 348)
    struct.pack_into("<8h", hdr, 40, 3, *lab.shape, 1, 1, 1, 1)
    struct.pack_into("<hh", hdr, 70, 2, 8)  # uint8, 8 bits
    struct.pack_into("<8f", hdr, 76, 1, *spacing, 1, 1, 1, 1)
    struct.pack_into("<f", hdr, 108, 352)
    hdr[123] = 2  # millimetres
    struct.pack_into("<h", hdr, 254, 1)  # sform
    for r in range(3):
        row = [0.0, 0.0, 0.0, origin[r]]
        row[r] = spacing[r]
        struct.pack_into("<4f", hdr, 280 + 16 * r, *row)
    hdr[344:348] = b"n+1\0"
    with gzip.open(path, "wb") as f:
        f.write(bytes(hdr) + b"\0" * 4 + lab.transpose(2, 1, 0).tobytes())


def volume_256(path):
    import numpy as np
    n, sp = 256, 0.5
    x = (np.arange(n) - (n - 1) / 2) * sp
    X, Y, Z = np.meshgrid(x, x, x, indexing="ij")
    lab = np.zeros((n, n, n), np.uint8)
    lab[(X / 60) ** 2 + (Y / 45) ** 2 + (Z / 35) ** 2 <= 1] = 1
    lab[(X - 15) ** 2 + Y ** 2 + Z ** 2 <= 15 ** 2] = 2
    write_nifti_labels(path, lab, (sp, sp, sp), (x[0], x[0], x[0]))


def torus_image(path, v=0.5):
    import numpy as np
    nx, nz = int(round(84 / v)), int(round(24 / v)) + 4
    x = (np.arange(nx) + 0.5) * v - 42
    z = (np.arange(nz) + 0.5) * v - nz * v / 2
    X, Y, Z = np.meshgrid(x, x, z, indexing="ij")
    lab = np.zeros(X.shape, np.uint8)
    lab[(np.sqrt(X ** 2 + Y ** 2) - 30) ** 2 + Z ** 2 <= 12 ** 2] = 1
    lab[(X - 30) ** 2 + Y ** 2 + Z ** 2 <= 5 ** 2] = 2
    write_nifti_labels(path, lab, (v, v, v), (x[0], x[0], z[0]))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--out", default="out/mesh_timing")
    ap.add_argument("--skip-256", action="store_true")
    ap.add_argument("--only", default="", help="run only the cases whose name contains this")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    sphere_obj(f"{a.out}/sphere.obj")
    torus_obj(f"{a.out}/torus.obj")
    liver = "scenarios/meshes/liver-smooth.obj"
    cases = [
        ("phantom 1 mm (labels 1, 2)", ["image", "tests/data/images/phantom_1mm.nii.gz", "--labels", "1=liver,2=tumour"]),
        ("phantom 0.8x0.8x2 mm", ["image", "tests/data/images/phantom_aniso.nii.gz", "--labels", "1=liver,2=tumour"]),
        ("sphere R 50 mm", ["surface", f"{a.out}/sphere.obj"]),
        ("torus 40/15 mm", ["surface", f"{a.out}/torus.obj"]),
        # The shipped livers' settings (scripts/meshes/liver_cgal.sh), scaled to the 16 cm liver.
        ("liver 16 cm ~2k (shipped)", ["surface", liver, "--scale", "0.025", "--repair", "--tets", "1000",
                                       "--facet-distance", "0.00075"]),
        ("liver 16 cm ~5k (shipped)", ["surface", liver, "--scale", "0.025", "--repair", "--tets", "4000",
                                       "--facet-distance", "0.0005"]),
        ("liver 16 cm ~15k", ["surface", liver, "--scale", "0.025", "--repair", "--tets", "12000"]),
    ]
    torus_image(f"{a.out}/torus_phantom.nii.gz")
    cases.append(("torus phantom 0.5 mm", ["image", f"{a.out}/torus_phantom.nii.gz", "--labels", "1=torus,2=inclusion"]))
    cases.append(("torus phantom 0.5 mm, --size 1.5 mm", ["image", f"{a.out}/torus_phantom.nii.gz", "--labels",
                                                          "1=torus,2=inclusion", "--size", "0.0015"]))
    if not a.skip_256:
        print("writing a 256^3 label volume ...", file=sys.stderr)
        volume_256(f"{a.out}/volume256.nii.gz")
        cases.append(("256^3 labels, 0.5 mm", ["image", f"{a.out}/volume256.nii.gz", "--labels", "1=organ,2=inclusion"]))
        cases.append(("256^3 labels, 0.5 mm, --size 1 mm", ["image", f"{a.out}/volume256.nii.gz", "--labels",
                                                            "1=organ,2=inclusion", "--size", "0.001"]))
    rows = []
    for name, args in cases:
        if a.only not in name:
            continue
        stem = f"{a.out}/" + "".join(c if c.isalnum() else "_" for c in name)
        times = []
        for _ in range(a.runs):
            t0 = time.perf_counter()
            r = subprocess.run(["build/stroma", "mesh", *args, "--out", stem + ".msh", "--no-png", "-q"],
                               capture_output=True, text=True)
            times.append(time.perf_counter() - t0)
            if r.returncode not in (0, 1):
                print(r.stderr, file=sys.stderr)
                sys.exit(1)
        j = json.load(open(stem + ".quality.json"))
        vols = "; ".join(
            f"{g['name']} {100 * g['relative_error']:+.2f} %" for g in j["regions"] if g["relative_error"] is not None)
        edge, unit = 1e3 * j["edge_length_m"]["mean"], "mm"  # every case's output is in metres
        rows.append(f"| {name} | {j['size_asked']} | {j['elements']:,} | {edge:.3g} {unit} | {statistics.median(times):.2f} | {j['dihedral_deg']['min']:.2f} | "
                    f"{j['radius_ratio']['min']:.3f} / {j['radius_ratio']['mean']:.3f} | {j['slivers']['count']} | {vols} | "
                    f"{1e3 * j['hausdorff_m']:.3g} mm |")
        print(rows[-1], flush=True)
    print("\n| case | asked | elements | mean edge | wall s (median) | min dihedral ° | radius ratio min / mean | slivers < 5° | "
          "volume vs input | Hausdorff |\n|---|---|---|---|---|---|---|---|---|---|")
    print("\n".join(rows))


if __name__ == "__main__":
    main()
