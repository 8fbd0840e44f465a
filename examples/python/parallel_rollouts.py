"""Rollouts in worker processes from one pickled snapshot (docs/PYTHON.md, "Many processes").

A probe has been brought down onto SOFA's liver (scenarios/regression/liver_probe_damage.yaml,
mesh units, a von Mises damage model); from that one state, each rollout presses on at its own
speed for `ticks` ticks and reports the largest force felt and the damage done. The rollouts run
in a multiprocessing pool: each worker compiles the scenario once (the pool's initializer) and
restores the snapshot, which travels pickled, before every rollout. With --check the same
rollouts also run here, one after the other, and must give the same numbers bit for bit.

    PYTHONPATH=build/python python3 examples/python/parallel_rollouts.py [--processes 2] [--check]
"""
import argparse
import multiprocessing
import os
import pickle
import sys
import time

import numpy as np

import stroma
from stroma.env import DATA_DIR

SCENARIO = os.path.join(DATA_DIR, "regression", "liver_probe_damage.yaml")
START = np.array([-1.5, 6.0, 0.5])  # above the liver's upper lobe (mesh units)

_worker = {}


def approach(sim, ticks=380, speed=2.0):
    """Brings the probe down from START at `speed` for `ticks` ticks; returns its height."""
    y = START[1]
    for _ in range(ticks):
        y -= speed * sim.time_step
        sim.set_pose(0, [START[0], y, START[2]])
        sim.step()
    return y


def rollout(sim, snapshot, y0, speed, ticks):
    """From `snapshot` (probe at height y0), presses down at `speed` for `ticks` ticks."""
    sim.restore(snapshot)
    y, peak = y0, 0.0
    for _ in range(ticks):
        y -= speed * sim.time_step
        sim.set_pose(0, [START[0], y, START[2]])
        sim.step()
        peak = max(peak, sim.feedback(0)["force"][1])
    d = sim.damage
    return {"speed": speed, "peak_force": peak, "max_damage": float(d.max()) if d.size else 0.0,
            "damaged": int(sim.damage_counts[1]), "tip_y": float(sim.positions[:, 1].max())}


def _init(scenario, snapshot, y0, ticks):
    _worker["sim"] = stroma.Simulation(scenario)
    _worker["args"] = (snapshot, y0, ticks)


def _run(speed):
    snapshot, y0, ticks = _worker["args"]
    return rollout(_worker["sim"], snapshot, y0, speed, ticks)


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--processes", type=int, default=os.cpu_count(), help="worker processes (default: the CPUs)")
    p.add_argument("--speeds", type=float, nargs="+", default=[0.05, 0.1, 0.15, 0.2, 0.3, 0.4],
                   help="press speeds, one rollout each (mesh units/s)")
    p.add_argument("--ticks", type=int, default=1000, help="ticks per rollout (1 ms each)")
    p.add_argument("--check", action="store_true", help="also run serially and require equal results")
    a = p.parse_args(argv)

    sim = stroma.Simulation(SCENARIO)
    y0 = approach(sim)
    snapshot = sim.snapshot()
    print(f"snapshot at t = {snapshot.time:.3f} s, probe at y = {y0:.3f}: {len(pickle.dumps(snapshot))} bytes pickled")

    t0 = time.perf_counter()
    # "spawn": workers start clean (no copy of this process's engine state), as they would on
    # another machine; the scenario and the snapshot reach them pickled.
    with multiprocessing.get_context("spawn").Pool(a.processes, _init, (SCENARIO, snapshot, y0, a.ticks)) as pool:
        results = pool.map(_run, a.speeds)
    t_par = time.perf_counter() - t0
    for r in results:
        print(f"  speed {r['speed']:4.2f}: peak force {r['peak_force']:7.4f}, max damage {r['max_damage']:.4f}, "
              f"damaged elements {r['damaged']}")
    print(f"{len(a.speeds)} rollouts of {a.ticks} ticks in {a.processes} processes: {t_par:.2f} s")

    if a.check:
        t0 = time.perf_counter()
        serial = [rollout(sim, snapshot, y0, s, a.ticks) for s in a.speeds]
        t_ser = time.perf_counter() - t0
        print(f"serially in this process: {t_ser:.2f} s")
        if serial != results:
            print("MISMATCH: the parallel rollouts differ from the serial ones", file=sys.stderr)
            return 1
        print("parallel = serial, bit for bit")
    return 0


if __name__ == "__main__":
    sys.exit(main())
