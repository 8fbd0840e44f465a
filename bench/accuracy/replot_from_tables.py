#!/usr/bin/env python3
"""Redraws the accuracy plots (docs/img/accuracy_<problem>.png) from the Markdown tables of
docs/ACCURACY.md, without rerunning `stroma bench accuracy`.

1. Parses the suite's tables in the sections "### cantilever_static", "### cantilever_dynamic",
   "### block_compression" and "### indentation ..." (the first table after each heading whose
   header starts "| sweep | configuration |").
2. Writes one CSV per problem in the suite's format (bench/accuracy/accuracy_suite.cpp, write_csv;
   columns problem,sweep,label,nodes,value,reference,error,ms_per_tick,s_per_sim_s,pareto,ok,
   time_error) to docs/data/accuracy_<problem>.csv. What the tables do not give is left empty
   (ms_per_tick of the peers on the static problems); -1 in time_error means "not computed", as in
   the suite.
3. Marks the Pareto front again with the suite's rule (mark_pareto): a valid point is off the front
   if another valid point of the same problem is at least as fast and at least as accurate and
   better in one (errors within 1e-4 relative count as equal). Not valid: failed runs and points
   that do not solve the stated problem (Bullet's raw neo-Hookean, "softer material" in the label).
   Differences from the tables' own Pareto column (the suite's, on unrounded figures) are printed.
4. Draws the plots with the suite's own gnuplot generator: `stroma bench accuracy --replot
   docs/data --out docs/img`, which also writes docs/data/accuracy_<problem>.gp and the numbers'
   table docs/data/accuracy_<problem>_pareto.md.

Run from anywhere: python3 bench/accuracy/replot_from_tables.py [--stroma build/stroma] [--no-plot]
Python 3 standard library only.
"""

import argparse
import csv
import io
import os
import re
import subprocess
import sys

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# The suite's references (accuracy_suite.cpp: kStaticReference, kF1Reference, kBlockForce, kIndentForce).
REFERENCE = {
    "cantilever_static": -1.4735e-3,
    "cantilever_dynamic": 16.100,
    "block_compression": 0.3049,
    "indentation": 0.019604,
}
# Heading that opens each problem's section (a prefix of the heading line).
HEADING = {
    "cantilever_static": "### cantilever_static",
    "cantilever_dynamic": "### cantilever_dynamic",
    "block_compression": "### block_compression",
    "indentation": "### indentation",
}
# Column of the measured value, and its factor to the CSV's unit (the CSV holds metres for the tip).
VALUE_COLUMN = {
    "cantilever_static": ("tip u_y (mm)", 1e-3),
    "cantilever_dynamic": ("f1 (Hz)", 1.0),
    "block_compression": ("top force (N)", 1.0),
    "indentation": ("force (N)", 1.0),
}
TIME_COLUMNS = ("solve s", "s to answer", "s per sim. s")
NUMBER = re.compile(r"[+-]?(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
HEADER = ["problem", "sweep", "label", "nodes", "value", "reference", "error", "ms_per_tick", "s_per_sim_s",
          "pareto", "ok", "time_error"]


def leading_number(cell):
    """The number a cell starts with (Unicode minus read as '-'), or None."""
    m = NUMBER.match(cell.strip().replace("\u2212", "-").replace("**", ""))
    return float(m.group(0)) if m else None


def cells(line):
    line = line.strip()
    return [c.strip() for c in line[1:-1].split("|")] if line.startswith("|") and line.endswith("|") else None


def find_table(lines, problem):
    """Header and rows of the problem's suite table: the first table after the heading."""
    start = next((i for i, l in enumerate(lines) if l.startswith(HEADING[problem])), None)
    if start is None:
        raise SystemExit(f"{problem}: heading '{HEADING[problem]}' not found")
    for i in range(start + 1, len(lines)):
        if lines[i].startswith("### ") or lines[i].startswith("## "):
            break
        c = cells(lines[i])
        if c and c[:2] == ["sweep", "configuration"]:
            rows = []
            for j in range(i + 2, len(lines)):  # skip the |---| line
                if not lines[j].startswith("|"):
                    break
                rows.append((j + 1, lines[j]))
            return c, rows
    raise SystemExit(f"{problem}: no '| sweep | configuration |' table after its heading")


def parse_problem(lines, problem, notes):
    header, rows = find_table(lines, problem)
    col = {name: k for k, name in enumerate(header)}
    value_name, unit = VALUE_COLUMN[problem]
    time_name = next(t for t in TIME_COLUMNS if t in col)
    points = []
    for lineno, line in rows:
        c = cells(line)
        if c is None or len(c) != len(header):
            notes.append(f"{problem}, ACCURACY.md line {lineno}: {len(c) if c else 0} cells for {len(header)} columns, "
                         f"row skipped: {line.strip()}")
            continue
        p = {
            "problem": problem, "sweep": c[col["sweep"]], "label": c[col["configuration"]],
            "nodes": int(c[col["nodes"]].replace(",", "")), "reference": REFERENCE[problem],
            "table_pareto": c[col["Pareto"]] == "●", "ms_per_tick": None, "time_error": -1.0,
        }
        error_cell, value_cell = c[col["error"]], c[col[value_name]]
        value, error = leading_number(value_cell), leading_number(error_cell)
        p["ok"] = not error_cell.startswith("failed") and value is not None and error is not None
        p["value"] = value * unit if p["ok"] else 0.0
        p["error"] = abs(error) / 100 if p["ok"] else 0.0
        if p["ok"] and value_cell != NUMBER.match(value_cell.replace("\u2212", "-")).group(0):
            notes.append(f"{problem}, line {lineno} ({p['label']}): value cell '{value_cell}' read as {value:g}")
        time = leading_number(c[col[time_name]])
        if time is None:
            notes.append(f"{problem}, line {lineno} ({p['label']}): no time in '{c[col[time_name]]}', row skipped")
            continue
        p["s_per_sim_s"] = time
        if "ms/tick" in col:
            p["ms_per_tick"] = leading_number(c[col["ms/tick"]])
        elif "(peer)" not in p["sweep"]:
            p["ms_per_tick"] = 0.0  # the suite writes 0 for its static solves; the peers' per-step times are not in the tables
        if "time-step share" in col and c[col["time-step share"]]:
            p["time_error"] = leading_number(c[col["time-step share"]]) / 100
        if "C3D4 same mesh (N)" in col:
            p["time_error"] = leading_number(c[col["C3D4 same mesh (N)"]])  # the suite's reused column
        if p["ok"] and time <= 0:
            notes.append(f"{problem}, line {lineno} ({p['label']}): time '{c[col[time_name]]}' rounds to 0: "
                         "kept, but a log axis cannot draw it")
        # Points that do not solve the stated problem (the suite's same_problem false).
        p["same_problem"] = "(softer material)" not in p["label"]
        points.append(p)
    return points


def mark_pareto(points):
    """accuracy_suite.cpp mark_pareto, on the tables' figures."""
    def no_worse(a, b):
        return a <= b * (1 + 1e-4) + 1e-12
    valid = [q for q in points if q["ok"] and q["same_problem"]]
    for p in points:
        p["pareto"] = p["ok"] and p["same_problem"]
        for q in valid:
            if q is p:
                continue
            err_no_worse, err_better = no_worse(q["error"], p["error"]), not no_worse(p["error"], q["error"])
            if q["s_per_sim_s"] <= p["s_per_sim_s"] and err_no_worse and (q["s_per_sim_s"] < p["s_per_sim_s"] or err_better):
                p["pareto"] = False
                break


def g(x, digits):
    return "" if x is None else f"{x:.{digits}g}"


def write_csv(path, points):
    out = io.StringIO()
    out.write(",".join(HEADER) + "\n")
    for p in points:
        out.write(",".join([
            p["problem"], f'"{p["sweep"]}"', f'"{p["label"]}"', str(p["nodes"]), g(p["value"], 8), g(p["reference"], 8),
            g(p["error"], 6), g(p["ms_per_tick"], 6), g(p["s_per_sim_s"], 6), "1" if p["pareto"] else "0",
            "1" if p["ok"] else "0", g(p["time_error"], 6)]) + "\n")
    with open(path, "w", encoding="utf-8") as f:
        f.write(out.getvalue())
    # Sanity: the file reads back with 12 columns per row (labels and sweeps hold commas).
    with open(path, encoding="utf-8") as f:
        assert all(len(r) == len(HEADER) for r in csv.reader(f))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--doc", default="docs/ACCURACY.md", help="the Markdown with the suite's tables (relative to the repository)")
    ap.add_argument("--data", default="docs/data", help="where the CSVs, gnuplot scripts and Pareto tables go")
    ap.add_argument("--img", default="docs/img", help="where the PNGs go")
    ap.add_argument("--stroma", default="build/stroma", help="the stroma binary (its --replot draws the plots)")
    ap.add_argument("--no-plot", action="store_true", help="write the CSVs only")
    a = ap.parse_args()
    os.chdir(REPO)  # relative paths: the gnuplot scripts written beside the CSVs then run from the repository root
    with open(a.doc, encoding="utf-8") as f:
        lines = f.read().splitlines()
    os.makedirs(a.data, exist_ok=True)
    notes = []
    for problem in REFERENCE:
        points = parse_problem(lines, problem, notes)
        mark_pareto(points)
        path = os.path.join(a.data, f"accuracy_{problem}.csv")
        write_csv(path, points)
        front = sum(p["pareto"] for p in points)
        print(f"{path}: {len(points)} points, {front} on the Pareto front")
        for p in points:
            if p["pareto"] != p["table_pareto"]:
                print(f"  Pareto differs from the table's column: {p['label']} ({p['sweep']}): "
                      f"table {'●' if p['table_pareto'] else '-'}, recomputed {'●' if p['pareto'] else '-'}")
    for n in notes:
        print("note:", n)
    if a.no_plot:
        return 0
    if not os.access(a.stroma, os.X_OK):
        sys.exit(f"{a.stroma} not found: build it (ninja -C build stroma) or pass --stroma, or use --no-plot")
    return subprocess.call([a.stroma, "bench", "accuracy", "--replot", a.data, "--out", a.img])


if __name__ == "__main__":
    sys.exit(main())
