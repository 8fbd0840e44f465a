#!/usr/bin/env python3
"""Multirate haptics (issue 14 §7): the tissue stepped every N ticks, each tool's force rendered
at every tick from the last finished step's local model (solver.fem_every, haptic_model).

For a scene (default: the 19,409-tet raptor at 0.32 m, scenarios/physical/raptor_0p32m.yaml)
this runs, headless and with the scene's tool script:
  * the reference: the full model stepped every tick (1 kHz), CG converged (1e-8);
  * the full model every tick with the scene's own solver settings;
  * for each N in --every: fem_every N with the secant model and with the held force, each tissue
    step budgeted to 0.9·N ms of wall time (as a served worker would be: its CG stops there).
Reported per run: the tissue step's wall time (p50, p99, max over the ticks that stepped; the
haptic ticks' own cost separately), whether the step fits the N ms it has in a served pipeline,
and the feedback force's error against the reference over every tick: RMS and max of |f − f_ref|
relative to the reference's largest force, and the RMS over the ticks in contact.

Prints a Markdown table (docs/PERFORMANCE.md, "Multirate").
Usage: bench/multirate.py [--stroma build/stroma] [--scene raptor_0p32m] [--every 5,10,20]
                          [--out /tmp/stroma_multirate]
"""
import argparse, csv, math, os, statistics, subprocess, sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from physical import scenario_with_solver  # noqa: E402


def run(stroma, scenario, out):
    subprocess.run([stroma, "run", scenario, "--out", out, "--quiet"], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    with open(os.path.join(out, "metrics.csv")) as f:
        return list(csv.DictReader(f))


def forces(rows, tool="probe"):
    return [(float(r[f"{tool}_fx"]), float(r[f"{tool}_fy"]), float(r[f"{tool}_fz"])) for r in rows]


def pct(v, q):
    v = sorted(v)
    return v[min(len(v) - 1, int(q * len(v)))] if v else float("nan")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--stroma", default="build/stroma")
    ap.add_argument("--scene", default="raptor_0p32m")
    ap.add_argument("--every", default="5,10,20")
    ap.add_argument("--out", default="/tmp/stroma_multirate")
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    configs = [("reference: every tick, CG to 1e-8", 1, "max_iterations: 2000, tolerance: 1.0e-8, newton_iterations: 1, on_cg_cap: continue"),
               ("every tick, the scene's solver", 1, "")]
    for n in [int(x) for x in a.every.split(",")]:
        for model in ("secant", "hold"):
            configs.append((f"fem_every {n}, {model}", n,
                            f"fem_every: {n}, haptic_model: {model}, newton_iterations: 1, time_budget: {0.0009 * n:.4f}"))
    results = []
    ref = None
    for label, n, override in configs:
        path, tmp = scenario_with_solver(a.scene, override, reset=())
        out = os.path.join(a.out, f"run_{len(results)}")
        print(f"multirate: {label} ...", file=sys.stderr, flush=True)
        try:
            rows = run(a.stroma, path, out)
        finally:
            if tmp:
                os.remove(tmp)
        f = forces(rows)
        if ref is None:
            ref = f
        fmax = max(math.sqrt(x * x + y * y + z * z) for x, y, z in ref)
        err = [math.dist(p, q) for p, q in zip(f, ref)]
        contact = [e for e, q in zip(err, ref) if math.sqrt(q[0] ** 2 + q[1] ** 2 + q[2] ** 2) > 0.05 * fmax]
        stepped = [float(r["step_ms"]) for i, r in enumerate(rows) if i % n == 0]
        haptic = [float(r["step_ms"]) for i, r in enumerate(rows) if i % n != 0]
        results.append({
            "label": label, "n": n,
            "step_p50": pct(stepped, 0.5), "step_p99": pct(stepped, 0.99), "step_max": max(stepped),
            "haptic_p99_us": pct(haptic, 0.99) * 1e3 if haptic else float("nan"),
            "cg": statistics.mean(float(r["cg_iterations"]) for i, r in enumerate(rows) if i % n == 0),
            "rms": math.sqrt(sum(e * e for e in err) / len(err)) / fmax,
            "max": max(err) / fmax,
            "rms_contact": math.sqrt(sum(e * e for e in contact) / len(contact)) / fmax if contact else 0.0,
            "fmax": fmax,
        })
    print(f"\n{a.scene}, `bench/multirate.py --every {a.every}`; force errors relative to the reference's largest force "
          f"({results[0]['fmax']:.3f} N), over all {len(ref)} ticks\n")
    print("| run | tissue step ms p50 / p99 / max | fits its N ms? | CG it. per step | haptic tick p99 µs "
          "| force error RMS / max | RMS in contact |")
    print("|---|---|---|---|---|---|---|")
    for r in results:
        fits = "yes" if r["step_p99"] <= r["n"] else ("p50 only" if r["step_p50"] <= r["n"] else "no")
        hp = "" if math.isnan(r["haptic_p99_us"]) else f"{r['haptic_p99_us']:.1f}"
        print(f"| {r['label']} | {r['step_p50']:.2f} / {r['step_p99']:.2f} / {r['step_max']:.2f} | {fits} "
              f"| {r['cg']:.1f} | {hp} | {100 * r['rms']:.2f} % / {100 * r['max']:.2f} % "
              f"| {100 * r['rms_contact']:.2f} % |")


if __name__ == "__main__":
    main()
