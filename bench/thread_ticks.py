#!/usr/bin/env python3
"""Tick cost of a thread (issue 43; docs/PERFORMANCE.md, "Threads").

Runs a thread scene and the same scene without the thread, alternating, `--runs` times each
with `stroma run`, and prints each run's tick p50/p99, the collide/assemble/solve medians, the
mean CG iterations and how many ticks the budget cut — over the ticks from 3 s on.

The default scene is the issue's: scenarios/liver_suture_thread.yaml — the fine 16 cm liver with
the incision, the needle driven through both lips, the suture through its four punctures and
pulled tight — with the thread in `--segments` segments (default 100; the scenario's own is 40).
`--scene scenarios/liver_stitch_thread.yaml --segments 0` is the earlier figure's scene (the
needle through the intact liver, a 100-segment thread through two punctures; 0: as written).

    python3 bench/thread_ticks.py --runs 3 [--stroma build/stroma] [--scene S] [--segments N]

`--stiffness-every 1,4@0.00065`: the thread scene alone, once per value of `solver.stiffness_every`
in each round (alternating; `N@B`: with time_budget B seconds, else `--budget` or the scene's),
with the ticks over 0.9 ms, the solve's position error estimate and the grasper's force at the
end (a runaway shows there).

`--served SECONDS [--no-thread] [--stiffness-every N] [--budget B]`: instead, the scene (with its segments, or without its thread) served at 1 kHz with the other
core busy (bench/realtime.sh: the grasper's script from a client that resumes the paused server,
the scalpel's from a second client), printing the server's tick and deadline statistics.
"""
import argparse
import csv
import os
import re
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def absolute(text):
    text = text.replace("mesh: meshes/", "mesh: " + os.path.join(ROOT, "scenarios", "meshes") + "/")
    return text.replace("script: trajectories/", "script: " + os.path.join(ROOT, "scenarios", "trajectories") + "/")


def with_segments(src, dst, segments):
    """The scene with its (first) thread in `segments` segments (paths made absolute)."""
    text = open(src).read()
    a = text.index("threads:")
    if segments > 0:
        text = text[:a] + re.sub(r"segments: \d+", f"segments: {segments}", text[a:], count=1)
    open(dst, "w").write(absolute(text))


def without_thread(src, dst):
    """The scene without its `threads:` section (paths made absolute)."""
    text = open(src).read()
    a, b = text.index("threads:"), text.index("run: {duration")
    open(dst, "w").write(absolute(text[:a] + text[b:]))


def with_stiffness_every(path, n, budget=0.0):
    """The scene at `path` rewritten with solver.stiffness_every = n (and time_budget, if given)."""
    text = open(path).read()
    assert "solver: {" in text, "the scene's solver section is expected in flow style"
    text = re.sub(r"stiffness_every: \d+, ", "", text).replace("solver: {", f"solver: {{stiffness_every: {n}, ", 1)
    if budget > 0:
        text = re.sub(r"time_budget: [0-9.e-]+", f"time_budget: {budget}", text, count=1)
    open(path, "w").write(text)


def final_force(out, tool="grasper"):
    """The tool's force magnitude (N) in the last row of metrics.csv (nan if not recorded)."""
    rows = list(csv.DictReader(open(os.path.join(out, "metrics.csv"))))
    keys = [f"{tool}_f{c}" for c in "xyz"]
    if not rows or any(k not in rows[-1] for k in keys):
        return float("nan")
    return sum(float(rows[-1][k]) ** 2 for k in keys) ** 0.5


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
        "over": sum(1 for r in rows if float(r["step_ms"]) > 0.9) / len(rows),
        "err_p50": pct("error_position", 0.5), "err_p99": pct("error_position", 0.99),
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--stroma", default=os.path.join(ROOT, "build", "stroma"))
    ap.add_argument("--skip", type=int, default=3000, help="ticks left out at the start (default: 3 s)")
    ap.add_argument("--scene", default=os.path.join(ROOT, "scenarios", "liver_suture_thread.yaml"))
    ap.add_argument("--segments", type=int, default=100, help="the thread's segments (0: as the scene has it)")
    ap.add_argument("--served", type=float, default=0, help="serve the scene this many seconds instead")
    ap.add_argument("--no-thread", action="store_true", help="--served: the scene without its thread")
    ap.add_argument("--stiffness-every", default="", help="comma-separated values of solver.stiffness_every to compare")
    ap.add_argument("--budget", type=float, default=0, help="--stiffness-every: the solver's time_budget (s) instead of the scene's")
    a = ap.parse_args()
    if a.served > 0:
        with tempfile.TemporaryDirectory() as tmp:
            scene = os.path.join(tmp, "thread.yaml")
            if a.no_thread:
                without_thread(a.scene, scene)
            else:
                with_segments(a.scene, scene, a.segments)
            if a.stiffness_every:
                with_stiffness_every(scene, int(a.stiffness_every), a.budget)
            traj = os.path.join(ROOT, "scenarios", "trajectories")
            env = dict(os.environ, PAUSED="1", TOOL_NAME="grasper",
                       SECOND_TOOL="scalpel:" + os.path.join(traj, "liver_suture_scalpel.yaml"))
            return subprocess.run(["bench/realtime.sh", str(int(a.served)), "--busy", scene,
                                   os.path.join(traj, "liver_suture_thread_grasper.yaml")], cwd=ROOT, env=env).returncode
    if a.stiffness_every:
        # Each value N, or N@BUDGET (seconds) for a budget of its own.
        values = [(int(v.split("@")[0]), float(v.split("@")[1]) if "@" in v else a.budget)
                  for v in a.stiffness_every.split(",")]
        with tempfile.TemporaryDirectory() as tmp:
            for k in range(a.runs):
                for n, budget in values:
                    scene = os.path.join(tmp, f"thread_{n}.yaml")
                    with_segments(a.scene, scene, a.segments)
                    with_stiffness_every(scene, n, budget)
                    out = os.path.join(tmp, f"out_{n}")
                    r = run(a.stroma, scene, out, a.skip)
                    label = f"{n}" + (f" budget {1e3 * budget:.2f} ms" if budget > 0 else "")
                    print(f"run {k + 1} stiffness_every {label}: tick p50 {r['p50']:.3f} p99 {r['p99']:.3f} ms, "
                          f"{100 * r['over']:.2f} % over 0.9 ms; "
                          f"assemble p50 {r['assemble_p50']:.3f}; solve p50 {r['solve_p50']:.3f}; CG {r['cg_mean']:.1f}; "
                          f"cut by the budget {100 * r['cut']:.0f} %; solve's position error p50 {1e6 * r['err_p50']:.1f} "
                          f"p99 {1e6 * r['err_p99']:.1f} um; grasper at the end {final_force(out):.2f} N", flush=True)
        return 0
    with tempfile.TemporaryDirectory() as tmp:
        scene = os.path.join(tmp, "thread.yaml")
        with_segments(a.scene, scene, a.segments)
        bare = os.path.join(tmp, "nothread.yaml")
        without_thread(a.scene, bare)
        for k in range(a.runs):
            for name, path in (("thread", scene), ("none", bare)):
                r = run(a.stroma, path, os.path.join(tmp, name), a.skip)
                print(f"run {k + 1} {name:6s} tick p50 {r['p50']:.3f} p99 {r['p99']:.3f} ms; collide p50 {r['collide_p50']:.3f} "
                      f"p99 {r['collide_p99']:.3f}; assemble p50 {r['assemble_p50']:.3f}; solve p50 {r['solve_p50']:.3f}; "
                      f"CG {r['cg_mean']:.1f}; cut by the budget {100 * r['cut']:.0f} %", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
