"""Stroma: soft-tissue FEM for surgical simulation, from Python (docs/PYTHON.md).

    import stroma
    sim = stroma.Simulation("scenarios/cantilever_dynamic.yaml")
    sim.step(100)
    print(sim.time, sim.positions[-1])
"""
from ._stroma import Simulation, Snapshot  # noqa: F401

__all__ = ["Simulation", "Snapshot"]
