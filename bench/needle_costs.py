#!/usr/bin/env python3
"""What a needle's track points and rigid bodies cost a tick (docs/PERFORMANCE.md, "Needles").

Track points: the served needle
scene (scenarios/physical/liver_16cm_needle.yaml: the half-circle needle turned through the
16 cm liver and back) run headless with its track spacing set finer and finer — more track
points in the same tissue — without the time budget (so the solves run to the tolerance and the
cost is the work's, not the deadline's). Per variant: the most track points the needle had, and
per tick the stages' mean times (collide, assemble, solve, integrate: summary.json), medians over
the runs; the cost per track point is the slope of the tick against the points (least squares).

Rigid bodies: N plastic balls (radius 5 mm, 1200 kg/m^3) on a grid dropped 5 mm onto the 50 mm
block of 10 kPa tissue of scenarios/rigid_drop.yaml, 0.5 s (they land, bounce and rest: contact
with the tissue all along), N = 1, 4, 9, 16: the tick against N, the cost per body the slope.

Usage: python3 bench/needle_costs.py [--runs 3] [--spacings default,0.004,0.002,0.001] [--bodies 1,4,9,16]
  (after scripts/build.sh; ~15 s a run)
"""
import argparse
import csv
import json
import os
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.abspath(os.path.join(os.path.dirname(__file__), ".."))
SCENE = os.path.join(ROOT, "scenarios", "physical", "liver_16cm_needle.yaml")
STAGES = ("collide", "assemble", "solve", "integrate")


def variant(spacing, out_dir):
    """The scene with absolute paths, no time budget and (unless None) the track spacing set."""
    text = open(SCENE).read()
    base = os.path.dirname(SCENE)
    text = re.sub(r"(mesh|visual|script): \.\./", lambda m: "%s: %s/../" % (m.group(1), base), text)
    text = text.replace(", time_budget: 0.00085", "")
    if spacing is not None:
        text = text.replace("friction: {static: 4, kinetic: 2}}", "friction: {static: 4, kinetic: 2}, track_spacing: %g}" % spacing)
        assert "track_spacing" in text
    path = os.path.join(out_dir, "needle_%s.yaml" % ("default" if spacing is None else spacing))
    open(path, "w").write(text)
    return path


def run_once(stroma, scene, out):
    subprocess.run([stroma, "run", scene, "--out", out, "--quiet"], check=True, stdout=subprocess.DEVNULL)
    s = json.load(open(os.path.join(out, "summary.json")))
    stages = {k: s["stages"][k]["per_step_ms"] for k in STAGES}
    with open(os.path.join(out, "metrics.csv")) as f:
        points = max(int(r["needle_track_points"]) for r in csv.DictReader(f))
    return s["step_ms"]["mean"], stages, points


def balls(n, out_dir):
    """N balls on a 4 x 4 grid (12 mm apart) over the block, in the order of the grid."""
    mesh = os.path.join(ROOT, "scenarios", "meshes", "cube_tet4_h5p000mm.msh")
    text = """name: balls_%d
time_step: 0.001
gravity: [0, -9.81, 0]
solver: {integrator: implicit_euler, preconditioner: block_jacobi, tolerance: 1.0e-8}
bodies:
  - name: block
    mesh: %s
    material: {young_modulus: 1.0e4, poisson_ratio: 0.45, density: 1000, rayleigh_mass: 10}
    fixed:
      - box: {min: [-1, -1.0e-6, -1], max: [1, 1.0e-6, 1]}
rigid_bodies:
""" % (n, mesh)
    for k in range(n):
        i, j = k % 4, k // 4
        text += "  - {name: ball%d, shape: {type: sphere, radius: 0.005}, density: 1200, pose: {position: [%.4f, 0.06, %.4f]}}\n" % (
            k, 0.007 + 0.012 * i, 0.007 + 0.012 * j)
    text += "run: {duration: 0.5}\n"
    path = os.path.join(out_dir, "balls_%d.yaml" % n)
    open(path, "w").write(text)
    return path


def slope(xs, ys):
    mx, my = statistics.mean(xs), statistics.mean(ys)
    return sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sum((x - mx) ** 2 for x in xs)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--spacings", default="default,0.004,0.002,0.001")
    ap.add_argument("--bodies", default="1,4,9,16")
    ap.add_argument("--stroma", default=os.path.join(ROOT, "build", "stroma"))
    a = ap.parse_args()
    if not os.path.exists(a.stroma):
        sys.exit("needle_costs: %s not found: run scripts/build.sh first" % a.stroma)
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for sp in a.spacings.split(","):
            spacing = None if sp == "default" else float(sp)
            scene = variant(spacing, tmp)
            ticks, stage_runs, points = [], [], 0
            for r in range(a.runs):
                t, st, p = run_once(a.stroma, scene, os.path.join(tmp, "out_%s_%d" % (sp, r)))
                ticks.append(t)
                stage_runs.append(st)
                points = max(points, p)
                print("  spacing %s run %d: tick %.4f ms, %d track points" % (sp, r + 1, t, p), flush=True)
            med = {k: statistics.median(s[k] for s in stage_runs) for k in STAGES}
            rows.append((sp, points, statistics.median(ticks), med))
    print("\n| track spacing | track points (most) | tick mean (ms) | collide | assemble | solve | integrate |")
    print("|---|---|---|---|---|---|---|")
    for sp, p, t, med in rows:
        print("| %s | %d | %.4f | %.4f | %.4f | %.4f | %.4f |" % (sp, p, t, med["collide"], med["assemble"], med["solve"],
                                                             med["integrate"]))
    xs = [p for _, p, _, _ in rows]
    ys = [t for _, _, t, _ in rows]
    if len(set(xs)) > 1:
        print("\nper track point: %.2f us of tick (least squares over the variants' most points)" % (1e3 * slope(xs, ys)))
    body_rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for n in [int(v) for v in a.bodies.split(",") if v]:
            scene = balls(n, tmp)
            ticks, collide = [], []
            for r in range(a.runs):
                out = os.path.join(tmp, "out_%d_%d" % (n, r))
                subprocess.run([a.stroma, "run", scene, "--out", out, "--quiet", "--no-metrics"], check=True,
                               stdout=subprocess.DEVNULL)
                s = json.load(open(os.path.join(out, "summary.json")))
                ticks.append(s["step_ms"]["mean"])
                collide.append(s["stages"]["collide"]["per_step_ms"])
            body_rows.append((n, statistics.median(ticks), statistics.median(collide)))
            print("  %d balls: tick mean %.4f ms, collide %.4f ms" % (n, body_rows[-1][1], body_rows[-1][2]), flush=True)
    if body_rows:
        print("\n| balls in contact | tick mean (ms) | collide (ms) |")
        print("|---|---|---|")
        for n, t, c in body_rows:
            print("| %d | %.4f | %.4f |" % (n, t, c))
        if len(body_rows) > 1:
            print("\nper rigid body in contact: %.1f us of tick, %.1f us of collide" % (
                1e3 * slope([r[0] for r in body_rows], [r[1] for r in body_rows]),
                1e3 * slope([r[0] for r in body_rows], [r[2] for r in body_rows])))


if __name__ == "__main__":
    main()
