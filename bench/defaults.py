#!/usr/bin/env python3
"""Fast without tuning (issue 39): every scene run (a) as a user writes it — only
`integrator: implicit_euler` in its solver section (the untuned scenes: what they give, e.g. SOFA's
CG settings, cap 25 and tolerance 1e-9, nothing else), so the engine chooses the preconditioner,
its refresh and the cap policy — and (b) with the best configuration found by hand at the same tolerance and cap: the
fastest (median tick) of a grid of hand settings (jacobi, block_jacobi, warped_cholesky with its
refresh off, every 10 steps or `auto`; capped steps kept; and the scene's own shipped solver
settings without their time budget) among those that reach the tolerance on as many ticks as the
best of them, in one run, interleaved.

For each scene:
  * the grid: --grid-runs timing runs of every hand configuration (plus the scene as shipped,
    whose own tolerance, cap and budget may differ: shown for reference, not a candidate for b);
  * timing: --runs rounds of (a) and (b) alternated; medians of each run's tick p50 and p99 as
    `stroma run` measures them (a headless run's waits for a late refresh worker included; the
    figures without them, what `serve` would see, go to defaults.json), CG iterations; for
    multirate scenes the mean tick stands for the p50;
  * error: (a), (b) and a converged run (CG to 1e-10, cap 5,000, the warped factor) over the same
    ticks, the state every --every ticks: the largest nodal distance from the converged run
    relative to its largest displacement, and the largest difference of the first tool's
    feedback force relative to its largest converged value.

Scenes: every shipped dynamic scenario (scenarios/*.yaml, scenarios/physical/*.yaml) and the
untuned scenes of scenarios/untuned/, written as users write them: SOFA's liver and beam with
SOFA's CG settings (liver_sofa_cg, beam_k6_sofa_cg), a stiff organ, the 100 kPa Armadillo lying
and standing, a thin plate, a 12,580-tet body. Multirate scenes keep `fem_every` and
`haptic_model` in (a): they are the scene.

Prints a Markdown table (docs/PERFORMANCE.md, "The engine chooses") and writes everything to
--out (summary.json of every run). Machines are shared and noisy: use several runs.

Usage: bench/defaults.py [--stroma build/stroma] [--runs 3] [--steps 2000] [--every 50]
                         [--scenes a,b] [--list] [--out /tmp/stroma_defaults]
"""
import argparse, csv, glob, json, math, os, re, statistics, subprocess, sys

import yaml

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SOFA = {"max_iterations": 25, "tolerance": 1.0e-9}
KEEP = ("integrator", "fem_every", "haptic_model")  # what (a) keeps of a scene's solver section
HAND = [  # (label, settings) of the hand grid for (b)
    ("jacobi", {"preconditioner": "jacobi", "on_cg_cap": "continue"}),
    ("block_jacobi", {"preconditioner": "block_jacobi", "on_cg_cap": "continue"}),
    ("warped, refresh off", {"preconditioner": "warped_cholesky", "preconditioner_refresh": "off",
                             "on_cg_cap": "continue"}),
    ("warped, refresh 10", {"preconditioner": "warped_cholesky", "preconditioner_refresh": 10,
                            "on_cg_cap": "continue"}),
    ("warped, refresh auto", {"preconditioner": "warped_cholesky", "preconditioner_refresh": "auto",
                              "on_cg_cap": "continue"}),
]
CONVERGED = {"preconditioner": "warped_cholesky", "max_iterations": 5000, "tolerance": 1.0e-10,
             "on_cg_cap": "continue"}


def scenes():
    """(name, path, base solver of (a), the tuned file shown as shipped) of every scene. (a) keeps
    what a user writes for the physics and the accuracy: the integrator, multirate settings and —
    in scenarios/untuned/, written as users write them — the cap and tolerance given (SOFA's)."""
    out = []
    tuned_for = {"untuned/liver_sofa_cg.yaml": "liver_sofa_settings.yaml"}
    for path in sorted(glob.glob(os.path.join(ROOT, "scenarios", "*.yaml")) +
                       glob.glob(os.path.join(ROOT, "scenarios", "physical", "*.yaml")) +
                       glob.glob(os.path.join(ROOT, "scenarios", "untuned", "*.yaml"))):
        doc = yaml.safe_load(open(path))
        solver = doc.get("solver") or {}
        if solver.get("integrator", "implicit_euler") != "implicit_euler":
            continue  # static scenes have no ticks
        rel = os.path.relpath(path, os.path.join(ROOT, "scenarios"))
        name = rel[:-5].replace("/", ":")
        if name == "liver_sofa_settings":
            continue  # the tuned form of untuned:liver_sofa_cg: one of its (b) candidates
        base = {k: solver[k] for k in ("max_iterations", "tolerance") if k in solver} if rel.startswith("untuned/") else {}
        out.append((name, path, base, os.path.join(ROOT, "scenarios", tuned_for.get(rel, rel))))
    return out


def variant(path, name, tag, solver_extra, base, tuned_from=None):
    """A copy of the scene next to it (relative paths still resolve) with its solver section
    replaced: the kept keys, `base` (a's settings), then `solver_extra`. With `tuned_from`, that
    file's solver section instead, without its time budget, at (a)'s tolerance and cap (the
    shipped tuning as a hand candidate for b). Returns its path."""
    doc = yaml.safe_load(open(path))
    old = doc.get("solver") or {}
    solver = {k: old[k] for k in KEEP if k in old}
    solver.setdefault("integrator", "implicit_euler")
    if tuned_from:
        solver.update((yaml.safe_load(open(tuned_from)).get("solver") or {}))
        for k in ("time_budget", "max_iterations", "tolerance"):
            solver.pop(k, None)
    solver.update(base)
    solver.update(solver_extra)
    doc["solver"] = solver
    doc["name"] = f"{doc.get('name', name)}"
    tmp = os.path.join(os.path.dirname(path), f".defaults_{name.replace(':', '_')}_{tag}.yaml")
    with open(tmp, "w") as f:
        yaml.safe_dump(doc, f, sort_keys=False)
    return tmp


def run(stroma, scenario, out, steps, extra):
    r = subprocess.run([stroma, "run", scenario, "--out", out, "--quiet", "--steps", str(steps)] + extra,
                       stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"{scenario}: exit {r.returncode}: {r.stderr.strip()[-500:]}")
    return json.load(open(os.path.join(out, "summary.json")))


def tick_figures(s, multirate=False):
    """(p50, p99, p50 and p99 without the headless waits for a late refresh worker — what
    `serve` would see —, CG iterations). The ticks as `stroma run` measures them, waits and all:
    a headless user waits them too. Multirate scenes step the tissue every few ticks, so their
    p50 is a tick without a step: the mean stands in for it."""
    w = s.get("warped_preconditioner", {}).get("step_ms_without_refresh_waits", s["step_ms"])
    t = s["step_ms"]
    return (t["mean"] if multirate else t["p50"]), t["p99"], (w["mean"] if multirate else w["p50"]), w["p99"], \
        s["cg_iterations"]["mean"]


def states(out):
    series = {}
    for name in sorted(os.listdir(out)):
        if name.startswith("state_") and name.endswith(".vtu"):
            text = open(os.path.join(out, name)).read()
            m = re.search(r'Name="displacement"[^>]*>(.*?)</DataArray>', text, flags=re.S)
            v = [float(x) for x in m.group(1).split()]
            series[name] = [v[i:i + 3] for i in range(0, len(v), 3)]
    return series


def feedback(out):
    rows = list(csv.DictReader(open(os.path.join(out, "metrics.csv"))))
    cols = [c for c in (rows[0].keys() if rows else []) if c.endswith("_feedback_fx")]
    if not cols:
        return None
    t = cols[0][:-len("_feedback_fx")]
    return [[float(r[f"{t}_feedback_f{c}"]) for c in "xyz"] for r in rows]


def errors(out, ref):
    """(displacement error, its scale in m, force error, its scale in N); None where the runs'
    meshes differ (a cut that happened at another tick)."""
    u, uref = states(out), states(ref)
    scale = max((math.dist(d, (0, 0, 0)) for s in uref.values() for d in s), default=0.0)
    if any(len(u.get(k, [])) != len(uref[k]) for k in uref) or scale == 0:
        du = None
    else:
        du = max(math.dist(a, b) for k in uref for a, b in zip(u[k], uref[k])) / scale
    f, fref = feedback(out), feedback(ref)
    if f is None or fref is None:
        return du, scale, None, 0.0
    fscale = max(math.dist(x, (0, 0, 0)) for x in fref)
    df = max(math.dist(a, b) for a, b in zip(f, fref)) / fscale if fscale > 0 else None
    return du, scale, df, fscale


def pct(x):
    return "—" if x is None else f"{100 * x:.2f} %"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--stroma", default=os.path.join(ROOT, "build", "stroma"))
    ap.add_argument("--runs", type=int, default=3, help="timing rounds of (a) and (b), alternated")
    ap.add_argument("--grid-runs", type=int, default=2, help="rounds of the hand grid that picks (b)")
    ap.add_argument("--steps", type=int, default=2000, help="ticks per run")
    ap.add_argument("--every", type=int, default=50, help="ticks between state samples for the error")
    ap.add_argument("--scenes", default="", help="comma-separated names (default: all; --list shows them)")
    ap.add_argument("--list", action="store_true", help="list the scenes and exit")
    ap.add_argument("--out", default="/tmp/stroma_defaults")
    a = ap.parse_args()
    todo = scenes()
    if a.list:
        for n, p, _, _ in todo:
            print(n, os.path.relpath(p, ROOT))
        return
    if a.scenes:
        want = a.scenes.split(",")
        unknown = set(want) - {n for n, _, _, _ in todo}
        if unknown:
            sys.exit(f"defaults.py: unknown scene(s) {', '.join(sorted(unknown))} (see --list)")
        todo = [t for t in todo if t[0] in want]
    print("| scene | nodes / tets | (a) the engine's choice | (a) tick p50 / p99 ms | (b) best by hand | "
          "(b) tick p50 / p99 ms | a/b p50 / p99 | CG it. a / b | displacement error a / b | force error a / b "
          "| as shipped p50 / p99 ms |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    results = []
    for name, path, base, tuned in todo:
        d = os.path.join(a.out, name.replace(":", "_"))
        tmps = []
        try:
            pa = variant(path, name, "a", {}, base)
            tmps.append(pa)
            hand = []
            for k, (label, extra) in enumerate(HAND):
                hand.append((label, variant(path, name, f"h{k}", extra, base)))
                tmps.append(hand[-1][1])
            tuned_solver = (yaml.safe_load(open(tuned)).get("solver") or {})
            if any(k not in ("integrator", "fem_every", "haptic_model", "max_iterations", "tolerance", "time_budget")
                   for k in tuned_solver):  # the scene ships hand settings: one more candidate
                hand.append(("as tuned, at (a)'s tolerance", variant(path, name, "tuned", {}, base, tuned_from=tuned)))
                tmps.append(hand[-1][1])
            shipped = tuned  # exactly as shipped (its own tolerance, cap and budget)
            multirate = (yaml.safe_load(open(path)).get("solver") or {}).get("fem_every", 1) > 1
            # The grid, --grid-runs rounds of every hand configuration, then (b) = the fastest
            # median p50 among those that reach the tolerance as often as the best of them.
            grid = []
            for label, p in hand:
                grid.append([[], label, p, None])
            for r in range(a.grid_runs):
                for g in grid:
                    s = run(a.stroma, g[2], os.path.join(d, "grid", g[1].replace(" ", "_").replace(",", "") + f"_{r}"),
                            a.steps, ["--no-metrics"])
                    g[0].append(tick_figures(s, multirate)[0])
                    g[3] = s
                    print(f"defaults.py: {name}: {g[1]}: p50 {g[0][-1]:.3f} ms, "
                          f"{s['cg_iterations']['mean']:.1f} it.", file=sys.stderr, flush=True)
            grid = [(statistics.median(g[0]), g[1], g[2], g[3]) for g in grid]
            sh = run(a.stroma, shipped, os.path.join(d, "shipped"), a.steps, ["--no-metrics"])
            # (b) must reach the tolerance as often as (a) can: candidates whose solves reached it
            # on fewer ticks than the best candidate did are out (a capped Jacobi is fast, not b).
            def reached(g):
                t = g[3]["solver"].get("tolerance_reached", {})
                return t.get("ticks", 0)
            best_reach = max(reached(g) for g in grid)
            b_p50, b_label, pb, _ = min((g for g in grid if reached(g) >= 0.99 * best_reach), key=lambda g: g[0])
            # Timing rounds, (a) and (b) alternated.
            fa, fb = [], []
            for r in range(a.runs):
                sa = run(a.stroma, pa, os.path.join(d, f"a_{r}"), a.steps, ["--no-metrics"])
                sb = run(a.stroma, pb, os.path.join(d, f"b_{r}"), a.steps, ["--no-metrics"])
                fa.append(tick_figures(sa, multirate))
                fb.append(tick_figures(sb, multirate))
                print(f"defaults.py: {name}: round {r + 1}/{a.runs}", file=sys.stderr, flush=True)
            choice = sa["solver"]
            # Errors against a converged run.
            conv = variant(path, name, "conv", CONVERGED, base)
            tmps.append(conv)
            ev = ["--vtu-every", str(a.every)]
            run(a.stroma, conv, os.path.join(d, "converged"), a.steps, ev)
            run(a.stroma, pa, os.path.join(d, "a_err"), a.steps, ev)
            run(a.stroma, pb, os.path.join(d, "b_err"), a.steps, ev)
            ea = errors(os.path.join(d, "a_err"), os.path.join(d, "converged"))
            eb = errors(os.path.join(d, "b_err"), os.path.join(d, "converged"))
        except RuntimeError as e:
            print(f"| {name} | failed: {e} |", flush=True)
            continue
        finally:
            for t in tmps:
                if os.path.exists(t):
                    os.remove(t)
        med = statistics.median
        a50, a99 = med(f[0] for f in fa), med(f[1] for f in fa)
        b50, b99 = med(f[0] for f in fb), med(f[1] for f in fb)
        ita, itb = med(f[4] for f in fa), med(f[4] for f in fb)
        sp = tick_figures(sh, multirate)
        pc = choice["preconditioner"] + (f", refresh {choice['preconditioner_refresh']}"
                                         if "preconditioner_refresh" in choice else "")
        row = {"scene": name, "nodes": sa["nodes"], "tets": sa["elements"], "a_choice": pc, "a_p50": a50, "a_p99": a99,
               "b": b_label, "b_p50": b50, "b_p99": b99, "a_it": ita, "b_it": itb, "a_err": ea, "b_err": eb,
               "shipped_p50": sp[0], "shipped_p99": sp[1], "multirate": multirate,
               "a_without_waits": [(f[2], f[3]) for f in fa], "b_without_waits": [(f[2], f[3]) for f in fb],
               "grid": [(g[1], g[0]) for g in grid]}
        results.append(row)
        print(f"| {name} | {sa['nodes']} / {sa['elements']} | {pc} | {a50:.3f} / {a99:.3f} | {b_label} | "
              f"{b50:.3f} / {b99:.3f} | {a50 / b50:.2f} / {a99 / b99:.2f} | {ita:.1f} / {itb:.1f} | "
              f"{pct(ea[0])} / {pct(eb[0])} | {pct(ea[2])} / {pct(eb[2])} | {sp[0]:.3f} / {sp[1]:.3f} |", flush=True)
    with open(os.path.join(a.out, "defaults.json"), "w") as f:
        json.dump(results, f, indent=1)


if __name__ == "__main__":
    main()
