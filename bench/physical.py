#!/usr/bin/env python3
"""The physical-scale benchmark set (issue 14, §4): organs in SI units with realistic tissue and a
tool pressing and sliding in each, timed and compared with a converged solve of the same run.

Scenes (scenarios/physical/, each states its units, scale and support):
  liver_16cm        SOFA's liver, 596 tets, 16 cm, rho 1060, E 5 kPa, nu 0.45, on its lower face
  liver_fine_16cm   the same liver meshed finer by gmsh (3,876 tets)
  liver_16cm_locking_free  the 596-tet liver at nu 0.49 with locking-free elements (F-bar-patch, warped)
  armadillo_0p2m    the Armadillo, 4,406 tets, 0.2 m, rho 1000, E 10 kPa, nu 0.45, on its back
  *_warped          the same with the warped Cholesky preconditioner, refreshed on a worker thread
  beam_k6_converged SOFA's beam k6, 6,480 tets, SI, CG to 1e-6 every tick
  beam_k6_sofa      the same beam with SOFA's settings (CG capped at 25)

For each scene:
  * timing: --runs headless runs of the scene as shipped (--no-metrics); the median over runs
    of each run's tick p50, p99 and max, and the CG iterations;
  * error: one run of the scene as shipped and one converged run (CG to a relative residual of
    1e-10, cap 5,000), both writing the whole state every --every ticks. Displacement error:
    the largest nodal distance between the two runs over the samples, relative to the largest
    converged nodal displacement over the run. Feedback-force error: the largest difference of
    the tool's feedback force over all ticks, relative to the largest converged feedback force.

Prints a Markdown table (docs/PERFORMANCE.md). Machines are shared and noisy: use many runs.

Usage: bench/physical.py [--stroma build/stroma] [--runs 5] [--every 50] [--scenes a,b]
                         [--out /tmp/stroma_physical] [--variant 'stiffness_every: 4, time_budget: 0.00065']
"""
import argparse, csv, json, math, os, re, statistics, subprocess, sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SCENES = ["liver_16cm", "liver_16cm_locking_free", "liver_fine_16cm", "liver_fine_16cm_warped", "armadillo_0p2m", "armadillo_0p2m_warped",
          "beam_k6_converged", "beam_k6_sofa"]
CONVERGED = "max_iterations: 5000, tolerance: 1.0e-10"


def scenario_with_solver(scene, solver_override, reset=("max_iterations", "tolerance", "on_cg_cap", "time_budget"),
                         tag=""):
    """The scene's YAML with its solver map's settings overridden (a copy next to the original, so
    relative mesh paths still resolve): the keys given replace the scene's, and the `reset` keys
    are dropped (back to their defaults) unless given. Returns (path, temporary file or None)."""
    path = os.path.join(ROOT, "scenarios", "physical", scene + ".yaml")
    if not solver_override:
        return path, None
    src = open(path).read()
    m = re.search(r"solver: \{([^}]*)\}", src, flags=re.S)
    if not m:
        sys.exit(f"{os.path.basename(sys.argv[0])}: {path}: expected a flow-style 'solver: {{...}}' map")
    given = {kv.split(":")[0].strip() for kv in solver_override.split(",")}
    drop = given | set(reset)
    keep = [kv.strip() for kv in m.group(1).replace("\n", " ").split(",")
            if kv.strip() and kv.split(":")[0].strip() not in drop]
    src = src[:m.start()] + "solver: {" + ", ".join(keep + [solver_override]) + "}" + src[m.end():]
    tmp = os.path.join(os.path.dirname(path), f".physical_{scene}{tag}.yaml")
    with open(tmp, "w") as f:
        f.write(src)
    return tmp, tmp


def run(stroma, scenario, out, extra):
    subprocess.run([stroma, "run", scenario, "--out", out, "--quiet"] + extra, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)


def displacements(out):
    """Nodal displacements of every state_*.vtu in `out`, by file name."""
    series = {}
    for name in sorted(os.listdir(out)):
        if not (name.startswith("state_") and name.endswith(".vtu")):
            continue
        text = open(os.path.join(out, name)).read()
        m = re.search(r'Name="displacement"[^>]*>(.*?)</DataArray>', text, flags=re.S)
        v = [float(x) for x in m.group(1).split()]
        series[name] = [v[i:i + 3] for i in range(0, len(v), 3)]
    return series


def feedback(out, tool="probe"):
    rows = list(csv.DictReader(open(os.path.join(out, "metrics.csv"))))
    if rows and f"{tool}_feedback_fx" not in rows[0]:
        return [[0.0, 0.0, 0.0] for _ in rows]  # a scene without a tool
    return [[float(r[f"{tool}_feedback_f{c}"]) for c in "xyz"] for r in rows]


def errors(out, ref):
    u, uref = displacements(out), displacements(ref)
    scale = max(math.dist(d, (0, 0, 0)) for s in uref.values() for d in s)
    du = max(math.dist(a, b) for k in uref for a, b in zip(u[k], uref[k]))
    f, fref = feedback(out), feedback(ref)
    fscale = max(math.dist(x, (0, 0, 0)) for x in fref)
    df = max(math.dist(a, b) for a, b in zip(f, fref))
    return du / scale, scale, df / fscale if fscale > 0 else float("nan"), fscale


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stroma", default=os.path.join(ROOT, "build", "stroma"))
    ap.add_argument("--runs", type=int, default=5, help="timing runs per scene")
    ap.add_argument("--every", type=int, default=50, help="ticks between state samples for the error")
    ap.add_argument("--scenes", default=",".join(SCENES))
    ap.add_argument("--out", default="/tmp/stroma_physical")
    ap.add_argument("--variant", default="",
                    help="solver settings that replace the scene's in the timed and compared runs (e.g. "
                         "'stiffness_every: 4, time_budget: 0.00065'); the converged reference is the scene's own")
    a = ap.parse_args()
    print("| scene | nodes / tets | tick p50 / p99 / max ms | CG it. mean / max | displacement error (of max) | "
          "feedback error (of max) |")
    print("|---|---|---|---|---|---|")
    for scene in a.scenes.split(","):
        base = os.path.join(a.out, scene)
        shipped, variant_tmp = scenario_with_solver(scene, a.variant or None, reset=(), tag="_variant")
        p50, p99, mx, cg, cgmax = [], [], [], [], 0
        for r in range(a.runs):
            out = os.path.join(base, f"timing_{r}")
            run(a.stroma, shipped, out, ["--no-metrics"])
            s = json.load(open(os.path.join(out, "summary.json")))
            p50.append(s["step_ms"]["p50"]); p99.append(s["step_ms"]["p99"]); mx.append(s["step_ms"]["max"])
            cg.append(s["cg_iterations"]["mean"]); cgmax = max(cgmax, s["cg_iterations"]["max"])
            print(f"physical.py: {scene} timing run {r + 1}/{a.runs}", file=sys.stderr, flush=True)
        run(a.stroma, shipped, os.path.join(base, "shipped"), ["--vtu-every", str(a.every)])
        if variant_tmp:
            os.remove(variant_tmp)
        conv, tmp = scenario_with_solver(scene, CONVERGED)
        try:
            run(a.stroma, conv, os.path.join(base, "converged"), ["--vtu-every", str(a.every)])
        finally:
            os.remove(tmp)
        eu, us, ef, fs = errors(os.path.join(base, "shipped"), os.path.join(base, "converged"))
        s = json.load(open(os.path.join(base, "shipped", "summary.json")))
        med = statistics.median
        force = f"{100 * ef:.2f} % (of {fs:.3f} N)" if fs > 0 else "— (no tool)"
        print(f"| {scene} | {s['nodes']} / {s['elements']} | {med(p50):.3f} / {med(p99):.3f} / {med(mx):.3f} | "
              f"{med(cg):.1f} / {cgmax} | {100 * eu:.2f} % (of {1000 * us:.2f} mm) | {force} |", flush=True)


if __name__ == "__main__":
    main()
