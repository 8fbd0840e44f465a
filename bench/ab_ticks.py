#!/usr/bin/env python3
"""Before/after in one run: the same scenes ticked by two `stroma` binaries (say, a build of the
last commit and of the working tree), alternated run by run so that the machine's phases fall on
both. For each scene: the medians over --runs runs of each run's tick p50, p99 and mean (as
`stroma run` measures them: a headless run's waits for a late refresh worker included), the CG
iterations, and the final probe displacements' largest difference between the two binaries
relative to the largest displacement (0 where the arithmetic did not change).

Usage: bench/ab_ticks.py BEFORE AFTER [--runs 3] [--steps 3000] [--scenes a.yaml,b.yaml]
                         [--out /tmp/stroma_ab]
Scenes are paths relative to scenarios/ (default: the shipped tuned scenes).
"""
import argparse, json, math, os, statistics, subprocess, sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
TUNED = ["liver.yaml", "liver_sofa_settings.yaml", "armadillo.yaml", "physical/liver_16cm.yaml",
         "physical/liver_16cm_locking_free.yaml", "physical/liver_fine_16cm.yaml",
         "physical/liver_fine_16cm_warped.yaml", "physical/armadillo_0p2m.yaml",
         "physical/armadillo_0p2m_warped.yaml", "physical/beam_k6_converged.yaml", "physical/beam_k6_sofa.yaml"]


def run(stroma, scene, out, steps):
    r = subprocess.run([stroma, "run", os.path.join(ROOT, "scenarios", scene), "--steps", str(steps), "--out", out,
                        "--quiet", "--no-metrics"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit(f"ab_ticks.py: {stroma} {scene}: exit {r.returncode}: {r.stderr.strip()[-400:]}")
    return json.load(open(os.path.join(out, "summary.json")))


def probes(s):
    return [p["displacement"] for p in s.get("probes", {}).values()]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("before")
    ap.add_argument("after")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--scenes", default=",".join(TUNED))
    ap.add_argument("--out", default="/tmp/stroma_ab")
    a = ap.parse_args()
    print("| scene | before p50 / p99 / mean ms | after p50 / p99 / mean ms | after/before p50 / p99 | CG it. before / after "
          "| probe difference |")
    print("|---|---|---|---|---|---|")
    for scene in a.scenes.split(","):
        fig = {"before": [], "after": []}
        last = {}
        for r in range(a.runs):
            # Which binary goes first alternates by round: the second run of a pair measured up to
            # 1.15x slower whichever binary it was (2026-12-05, liver.yaml, 15 rounds each way).
            order = (("before", a.before), ("after", a.after))
            for side, exe in order if r % 2 == 0 else order[::-1]:
                s = run(exe, scene, os.path.join(a.out, scene.replace("/", "_")[:-5], f"{side}_{r}"), a.steps)
                fig[side].append((s["step_ms"]["p50"], s["step_ms"]["p99"], s["step_ms"]["mean"], s["cg_iterations"]["mean"]))
                last[side] = s
            print(f"ab_ticks.py: {scene}: round {r + 1}/{a.runs}", file=sys.stderr, flush=True)
        med = {k: [statistics.median(f[i] for f in v) for i in range(4)] for k, v in fig.items()}
        pb, pa = probes(last["before"]), probes(last["after"])
        scale = max((math.dist(p, (0, 0, 0)) for p in pb), default=0.0)
        diff = max((math.dist(x, y) for x, y in zip(pa, pb)), default=0.0)
        rel = f"{100 * diff / scale:.3g} %" if scale > 0 else "—"
        b, f = med["before"], med["after"]
        print(f"| {scene} | {b[0]:.3f} / {b[1]:.3f} / {b[2]:.3f} | {f[0]:.3f} / {f[1]:.3f} / {f[2]:.3f} | "
              f"{f[0] / b[0]:.2f} / {f[1] / b[1]:.2f} | {b[3]:.1f} / {f[3]:.1f} | {rel} |", flush=True)


if __name__ == "__main__":
    main()
