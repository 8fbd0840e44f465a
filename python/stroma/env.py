"""A Gymnasium-compatible environment over stroma.Simulation (docs/PYTHON.md), with no
dependency on gymnasium: reset() -> (obs, info), step(action) -> (obs, reward, terminated,
truncated, info), as Gymnasium's Env API.

ProbePressEnv: a spherical probe above the liver must press it to a target force without
damaging it. The scenario is scenarios/regression/liver_probe_damage.yaml (SOFA's liver in its
mesh units, a von Mises damage model); its probe script is overridden by the actions.

    action       float: the probe's vertical speed (units/s), clipped to [-max_speed, max_speed]
    observation  float64[4]: probe height above its start, the tissue's force on it along +y,
                 the largest element damage, the target force
    reward       -|F - target| / target per step, -10 when an element is damaged
    terminated   an element reached "damaged" (the damage model's onset)
    truncated    after max_steps actions
Each action lasts `ticks_per_action` engine ticks (1 ms each).
"""
import os

import numpy as np

from ._stroma import Simulation

#: The scenarios shipped with the package (a copy of the source tree's scenarios/ files it uses).
DATA_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data")


class ProbePressEnv:
    metadata = {"render_modes": []}

    def __init__(self, scenario=None, target_force=1.0, ticks_per_action=10, max_steps=300, max_speed=5.0,
                 start=(-1.5, 6.0, 0.5)):
        if scenario is None:
            scenario = os.path.join(DATA_DIR, "regression", "liver_probe_damage.yaml")
        self.sim = Simulation(scenario)
        self.target = float(target_force)
        self.ticks = int(ticks_per_action)
        self.max_steps = int(max_steps)
        self.max_speed = float(max_speed)
        self.start = np.array(start, dtype=float)
        self.y = self.start[1]
        self.steps = 0

    def _obs(self):
        fb = self.sim.feedback(0)
        d = self.sim.damage
        return np.array([self.y - self.start[1], fb["force"][1], float(d.max()) if d.size else 0.0, self.target])

    def reset(self, seed=None, options=None):
        self.sim.reset()
        self.y = self.start[1]
        self.steps = 0
        self.sim.set_pose(0, self.start.tolist())
        return self._obs(), {}

    def step(self, action):
        v = float(np.clip(np.asarray(action, dtype=float).reshape(-1)[0], -self.max_speed, self.max_speed))
        for _ in range(self.ticks):
            self.y += v * self.sim.time_step
            self.sim.set_pose(0, [self.start[0], self.y, self.start[2]])
            self.sim.step()
        self.steps += 1
        obs = self._obs()
        damaged = self.sim.damage_counts[1] > 0
        reward = -abs(obs[1] - self.target) / self.target - (10.0 if damaged else 0.0)
        return obs, reward, bool(damaged), self.steps >= self.max_steps, {"time": self.sim.time}
