#!/usr/bin/env python3
"""What `import stroma` costs against the engine run from C++ (issue 18 §1; docs/PERFORMANCE.md).

  1. The overhead of one Simulation.step() call: N calls of step(1) against one step(N) on the
     same scenario from the same state (the difference per tick is the Python → C++ call, the GIL
     release and re-acquire, and the per-call setup), alternated over --runs repetitions.
  2. 10,000 ticks from Python (one step(10000)) against `stroma run --steps 10000`'s stepping wall
     time (summary.json's wall_seconds), alternated.
  3. The per-call cost of set_pose() and feedback() (a control loop calls them every tick).

Medians over runs (the machine is shared and noisy). Usage:
    PYTHONPATH=build/python python3 bench/python_step.py [--build build] [--runs 7] [--steps 10000]
"""
import argparse
import json
import os
import pathlib
import statistics
import subprocess
import sys
import tempfile
import time

SOURCE = pathlib.Path(__file__).resolve().parents[1]

TET_MSH = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 0.01 0 0
3 0 0.01 0
4 0 0 0.01
$EndNodes
$Elements
1
1 4 2 1 1 1 2 3 4
$EndElements
"""
TET_YAML = """name: one_tet
time_step: 0.001
gravity: [0, 0, -9.81]
solver: {integrator: implicit_euler, linear_solver: cg, max_iterations: 100, tolerance: 1.0e-6}
bodies:
  - name: tet
    mesh: tet.msh
    material: {model: corotational, young_modulus: 5000, poisson_ratio: 0.45, density: 1000}
    fixed:
      - nodes: [0, 1, 2]
"""


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--build", default=str(SOURCE / "build"), help="build directory (its stroma binary)")
    p.add_argument("--scenario", default=str(SOURCE / "scenarios" / "liver.yaml"))
    p.add_argument("--runs", type=int, default=7)
    p.add_argument("--steps", type=int, default=10000)
    p.add_argument("--calls", type=int, default=20000, help="ticks per overhead measurement")
    a = p.parse_args()
    import stroma

    # 1. Per-call overhead, on one tetrahedron (a tick of ~1 us: the call's cost is not hidden in
    # the tick's noise).
    tiny = tempfile.TemporaryDirectory()
    with open(os.path.join(tiny.name, "tet.msh"), "w") as f:
        f.write(TET_MSH)
    with open(os.path.join(tiny.name, "tet.yaml"), "w") as f:
        f.write(TET_YAML)
    over = []
    for r in range(a.runs):
        sims = [stroma.Simulation(os.path.join(tiny.name, "tet.yaml")) for _ in range(2)]
        t0 = time.perf_counter()
        for _ in range(a.calls):
            sims[0].step(1)
        t_one = time.perf_counter() - t0
        t0 = time.perf_counter()
        sims[1].step(a.calls)
        t_many = time.perf_counter() - t0
        assert (sims[0].positions == sims[1].positions).all(), "the same ticks either way"
        over.append((t_one - t_many) / a.calls * 1e6)
        print(f"run {r + 1}: step(1) x {a.calls}: {t_one * 1e3:.1f} ms, step({a.calls}): {t_many * 1e3:.1f} ms, "
              f"overhead {over[-1]:.2f} us/call", flush=True)

    # 2. 10,000 ticks: Python against stroma run.
    py_s, run_s = [], []
    with tempfile.TemporaryDirectory() as out:
        for r in range(a.runs):
            subprocess.run([os.path.join(a.build, "stroma"), "run", a.scenario, "--steps", str(a.steps), "--out", out,
                            "--quiet", "--no-metrics"], check=True, stderr=subprocess.DEVNULL, stdout=subprocess.DEVNULL)
            with open(os.path.join(out, "summary.json")) as f:
                run_s.append(json.load(f)["wall_seconds"])
            sim = stroma.Simulation(a.scenario)
            t0 = time.perf_counter()
            sim.step(a.steps)
            py_s.append(time.perf_counter() - t0)
            print(f"run {r + 1}: {a.steps} ticks: stroma run {run_s[-1]:.3f} s, Python {py_s[-1]:.3f} s "
                  f"({py_s[-1] / run_s[-1]:.3f}x)", flush=True)

    # 3. set_pose and feedback.
    sim = stroma.Simulation(a.scenario)
    n = 20000
    t0 = time.perf_counter()
    for _ in range(n):
        sim.set_pose(0, [0.0, 5.0, 0.0])
    t_pose = (time.perf_counter() - t0) / n * 1e6
    t0 = time.perf_counter()
    for _ in range(n):
        sim.feedback(0)
    t_fb = (time.perf_counter() - t0) / n * 1e6

    ratios = [p_ / r_ for p_, r_ in zip(py_s, run_s)]
    print()
    print(f"scenario {os.path.relpath(a.scenario, SOURCE)}, {a.runs} runs, medians:")
    print(f"  step() call overhead (one tetrahedron): {statistics.median(over):.2f} us/call (min {min(over):.2f}, max {max(over):.2f})")
    print(f"  {a.steps} ticks: stroma run {statistics.median(run_s):.3f} s, Python {statistics.median(py_s):.3f} s, "
          f"ratio {statistics.median(ratios):.3f} (min {min(ratios):.3f}, max {max(ratios):.3f})")
    print(f"  set_pose() {t_pose:.2f} us/call, feedback() {t_fb:.2f} us/call")
    return 0


if __name__ == "__main__":
    sys.exit(main())
