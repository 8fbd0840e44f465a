#!/usr/bin/env python3
"""Tick cost of a thread (issue 43; docs/PERFORMANCE.md, "Threads").

Runs scenarios/liver_stitch_thread.yaml (the fine 16 cm liver, its half-circle needle turned
through it, a 100-segment suture tied to the needle) and the same scene without the thread,
alternating, `--runs` times each with `stroma run`, and prints each run's tick p50/p99, the
collide/assemble/solve medians, the mean CG iterations and how many ticks the budget cut — over
the ticks from 3 s on (the needle's approach, the turn, the regrasp, the pull).

    python3 bench/thread_ticks.py --runs 3 [--stroma build/stroma]
"""
import argparse
import csv
import os
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def without_thread(src, dst):
    """The scene without its `threads:` section (paths made absolute)."""
    text = open(src).read()
    a, b = text.index("threads:"), text.index("run: {duration")
    text = text[:a] + text[b:]
    text = text.replace("mesh: meshes/", "mesh: " + os.path.join(ROOT, "scenarios", "meshes") + "/")
    text = text.replace("script: trajectories/", "script: " + os.path.join(ROOT, "scenarios", "trajectories") + "/")
    open(dst, "w").write(text)


def run(stroma, scene, out, skip):
    subprocess.run([stroma, "run", scene, "--out", out, "--quiet"], check=True, capture_output=True)
    rows = list(csv.DictReader(open(os.path.join(out, "metrics.csv"))))[skip:]

    def pct(key, q):
        v = sorted(float(r[key]) for r in rows)
        return v[min(len(v) - 1, int(q * len(v)))]

    return {
        "p50": pct("step_ms", 0.5), "p99": pct("step_ms", 0.99),
        "collide_p50": pct("collide_ms", 0.5), "collide_p99": pct("collide_ms", 0.99),
        "assemble_p50": pct("assemble_ms", 0.5), "solve_p50": pct("solve_ms", 0.5),
        "cg_mean": statistics.mean(float(r["cg_iterations"]) for r in rows),
        "cut": sum(1 for r in rows if r["degradation"] != "none") / len(rows),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--stroma", default=os.path.join(ROOT, "build", "stroma"))
    ap.add_argument("--skip", type=int, default=3000, help="ticks left out at the start (default: 3 s)")
    a = ap.parse_args()
    scene = os.path.join(ROOT, "scenarios", "liver_stitch_thread.yaml")
    with tempfile.TemporaryDirectory() as tmp:
        bare = os.path.join(tmp, "liver_stitch_nothread.yaml")
        without_thread(scene, bare)
        for k in range(a.runs):
            for name, path in (("thread", scene), ("none", bare)):
                r = run(a.stroma, path, os.path.join(tmp, name), a.skip)
                print(f"run {k + 1} {name:6s} tick p50 {r['p50']:.3f} p99 {r['p99']:.3f} ms; collide p50 {r['collide_p50']:.3f} "
                      f"p99 {r['collide_p99']:.3f}; assemble p50 {r['assemble_p50']:.3f}; solve p50 {r['solve_p50']:.3f}; "
                      f"CG {r['cg_mean']:.1f}; cut by the budget {100 * r['cut']:.0f} %", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
