#!/usr/bin/env python3
"""Inexact solves on physical-scale scenes (issue 14, §2): SOFA's beam k6 and the Armadillo at
0.15 m, with CG capped at 5, 10, 25 iterations (the capped step kept) and with tick budgets of
0.3, 0.6, 0.9 ms, each run 1 s and compared with a converged run (CG to 1e-10) over the same 1 s.
Prints a Markdown table: energy rise (worst rise of the total mechanical energy above its running
maximum, relative to its largest magnitude: ≤ 0 means it never grew), ticks the energy guard
limited, the probe's vertical displacement error (largest over the second, relative to the
largest converged displacement; and at 1 s), tick p50/p99 and CG iterations.

Usage: bench/inexact_solves.py [--stroma build/stroma] [--out /tmp/stroma_inexact]
"""
import argparse, csv, os, re, subprocess, sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = [("beam_k6_sofa.yaml", "tip"), ("armadillo_0p15m.yaml", "head")]
CONFIGS = [("converged (CG 1e-10)", "max_iterations: 5000, tolerance: 1.0e-10"),
           ("cap 5", "max_iterations: 5, tolerance: 1.0e-10, on_cg_cap: continue"),
           ("cap 10", "max_iterations: 10, tolerance: 1.0e-10, on_cg_cap: continue"),
           ("cap 25", "max_iterations: 25, tolerance: 1.0e-10, on_cg_cap: continue"),
           ("budget 0.3 ms", "max_iterations: 2000, tolerance: 1.0e-10, on_cg_cap: continue, time_budget: 0.0003"),
           ("budget 0.6 ms", "max_iterations: 2000, tolerance: 1.0e-10, on_cg_cap: continue, time_budget: 0.0006"),
           ("budget 0.9 ms", "max_iterations: 2000, tolerance: 1.0e-10, on_cg_cap: continue, time_budget: 0.0009")]


def run(stroma, scene, solver, out):
    src = open(os.path.join(ROOT, "scenarios", "physical", scene)).read()
    src = re.sub(r"solver: \{[^}]*\}", "solver: {integrator: implicit_euler, linear_solver: cg, preconditioner: jacobi, "
                 + solver + "}", src, flags=re.S)
    path = os.path.join(ROOT, "scenarios", "physical", ".inexact_tmp.yaml")
    with open(path, "w") as f:
        f.write(src)
    try:
        subprocess.run([stroma, "run", path, "--out", out, "--quiet"], check=True, stdout=subprocess.DEVNULL,
                       stderr=subprocess.DEVNULL)
    finally:
        os.remove(path)
    return list(csv.DictReader(open(os.path.join(out, "metrics.csv"))))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stroma", default=os.path.join(ROOT, "build", "stroma"))
    ap.add_argument("--out", default="/tmp/stroma_inexact")
    a = ap.parse_args()
    print("| scene | solve | energy rise / scale | ticks energy-limited | probe dy error max / at 1 s | tick p50 / p99 ms | CG it. mean |")
    print("|---|---|---|---|---|---|---|")
    for scene, probe in SCENES:
        ref = None
        for label, solver in CONFIGS:
            rows = run(a.stroma, scene, solver, os.path.join(a.out, scene.split(".")[0], label.replace(" ", "_")))
            if ref is None:
                ref = rows
            e = [float(r["total_energy"]) for r in rows]
            top, rise = e[0], -1e300
            for x in e[1:]:
                rise, top = max(rise, x - top), max(top, x)
            scale = max(abs(x) for x in e)
            d = [float(r[probe + "_dy"]) for r in rows]
            dref = [float(r[probe + "_dy"]) for r in ref]
            amp = max(abs(x) for x in dref)
            err = max(abs(x - y) for x, y in zip(d, dref)) / amp
            end = abs(d[-1] - dref[-1]) / abs(dref[-1])
            ms = sorted(float(r["step_ms"]) for r in rows)
            limited = sum(1 for r in rows if float(r.get("energy_removed", "0") or 0) > 0)
            cg = sum(float(r["cg_iterations"]) for r in rows) / len(rows)
            print(f"| {scene} | {label} | {rise / scale:+.1e} | {limited} | {100 * err:.2f} % / {100 * end:.2f} % | "
                  f"{ms[len(ms) // 2]:.3f} / {ms[int(0.99 * len(ms))]:.3f} | {cg:.1f} |")
            sys.stdout.flush()


if __name__ == "__main__":
    main()
