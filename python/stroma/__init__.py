"""Stroma: soft-tissue FEM for surgical simulation, from Python (docs/PYTHON.md).

    import stroma
    sim = stroma.Simulation("scenarios/cantilever_dynamic.yaml")
    sim.step(100)
    print(sim.time, sim.positions[-1])
"""
import json as _json
import os as _os

from ._stroma import Simulation, Snapshot  # noqa: F401


def simulation_from_dict(scenario, base_dir="."):
    """A Simulation from a scenario given as a dict (the YAML file's structure). Relative mesh
    and script paths resolve against base_dir; errors name the field as "<dict>:line: field"
    (the dict is written as JSON, one key per line)."""
    text = _json.dumps(scenario, indent=1)
    return Simulation(text, "<dict>", _os.path.abspath(base_dir))


__all__ = ["Simulation", "Snapshot", "simulation_from_dict"]
