"""The suture demo's stitch as a Gymnasium environment (docs/PYTHON.md, "The stitch environment";
docs/THREAD.md, "Wound closure").

StitchEnv: one interrupted stitch across the cutting demo's incision — the scenario is
scenarios/liver_suture_thread.yaml (the fine 16 cm liver under tension across the incision, so it
gapes; a scalpel incises it; a grasper drives a half-circle needle through both lips with a
suture tied to its tail and anchored in the near lip). The scenario's scripts run once, when the
environment is made, up to `start_time` (13 s: the needle through both lips and out, lifted), and
that state is the start of every episode: reset() restores its snapshot (microseconds; nothing is
reloaded). The agent then moves the grasper holding the needle — and so the thread — to close the
wound without tearing the tissue.

    action       float32[3] in [-1, 1]: the grasper's velocity along world x, y, z as a fraction of
                 `speed` (default 20 mm/s), held for `ticks_per_action` ticks (1 ms each)
    observation  float64[8]: the grasper's displacement from its start (3, m), the force on it
                 (3, N), the gap at the stitch (m; as at the start once a puncture is lost) and
                 the largest element damage (0 without a damage model, as in the shipped scenario)
    reward       (gap_start - gap) / gap_start per action (the gap closed, 0 at the start, 1 when
                 closed), minus `damage_weight` times the largest damage, minus 10 when the
                 stitch fails
    terminated   the stitch failed: the thread left a puncture (fewer than the four it was
                 through), or the tissue's force on the grasper beyond `max_tension` (N)
    truncated    after max_steps actions

The gap at the stitch is the distance between the material points where the needle left the
near lip's cut face and entered the far lip's (the thread's 2nd and 3rd punctures): 1.7 mm at the
start. (The gap between the cut faces along the thread is smaller by the points' depth in them:
docs/THREAD.md.)

The environment steps unbudgeted — the scenario's `time_budget` is dropped — so an episode is the
same on every machine (with the budget, a solve cut short depends on the machine's speed).
Invalid actions are clipped into [-1, 1]; a non-finite one is refused (the grasper holds) and
counted in info["refused_actions"].
"""
import os
import re

import numpy as np

from ._stroma import Simulation
from .env import DATA_DIR, Box, _EnvBase


class StitchEnv(_EnvBase):
    metadata = {"render_modes": []}

    def __init__(self, scenario=None, start_time=13.0, ticks_per_action=20, max_steps=250, speed=0.02,
                 max_tension=4.0, damage_weight=10.0, render_mode=None):
        if render_mode is not None:
            raise ValueError("StitchEnv draws nothing (render_mode must be None; use stroma render or write_vtu)")
        self.render_mode = None
        if scenario is None:
            scenario = os.path.join(DATA_DIR, "liver_suture_thread.yaml")
        with open(scenario, encoding="utf-8") as f:
            text = f.read()
        # Unbudgeted: the solver's `time_budget` key dropped, in a flow mapping or on a line of its
        # own (the other lines' numbers kept for error messages).
        text = re.sub(r",\s*time_budget:\s*[0-9.eE+-]+", "", text)
        text = re.sub(r"(?m)^(\s*)time_budget:\s*[0-9.eE+-]+\s*(#.*)?$", r"\1", text)
        self.sim = Simulation(text, scenario, os.path.dirname(os.path.abspath(scenario)))
        names = [t["name"] for t in self.sim.tools]
        if "grasper" not in names:
            raise ValueError(f"{scenario}: StitchEnv needs a tool named 'grasper' (tools: {names})")
        self.tool = names.index("grasper")
        ticks = int(round(float(start_time) / self.sim.time_step))
        if self.sim.step(ticks) != ticks:
            raise RuntimeError(f"{scenario}: the scripted stitch did not run to {start_time} s")
        punctures = self.sim.threads[0]["punctures"] if self.sim.threads else []
        if len(punctures) != 4:
            raise RuntimeError(f"{scenario}: at {start_time} s the thread goes through {len(punctures)} punctures, "
                               "not the stitch's 4")
        self.start_snapshot = self.sim.snapshot()
        tool = self.sim.tools[self.tool]
        self.ticks = int(ticks_per_action)
        self.max_steps = int(max_steps)
        self.speed = min(float(speed), float(tool["max_speed"]))
        self.max_tension = float(max_tension)
        self.damage_weight = float(damage_weight)
        self.lo, self.hi = np.array(tool["workspace"]["min"]), np.array(tool["workspace"]["max"])
        self.start = np.array(self._grasper_position(), dtype=float)
        self.orientation = list(self.sim.tool_pose(self.tool)["orientation"])
        self.gap_start = self._gap()
        self.action_space = Box(low=-1.0, high=1.0, shape=(3,), dtype=np.float32)
        inf = np.inf
        self.observation_space = Box(low=np.array([-inf, -inf, -inf, -inf, -inf, -inf, 0.0, 0.0]),
                                     high=np.array([inf, inf, inf, inf, inf, inf, inf, 1.0]), dtype=np.float64)
        self.p = self.start.copy()
        self.steps = 0
        self.refused = 0

    def _grasper_position(self):
        return self.sim.tool_pose(self.tool)["position"]

    def _gap(self):
        ps = self.sim.threads[0]["punctures"]
        if len(ps) < 4:
            return float("nan")
        return float(np.linalg.norm(np.asarray(ps[1]["point"]) - np.asarray(ps[2]["point"])))

    def _obs(self):
        fb = self.sim.feedback(self.tool)
        d = self.sim.damage
        gap = self._gap()
        # A stitch that lost a puncture closes nothing: its gap reads as at the start, never as 0.
        return np.array([*(self.p - self.start), *fb["force"], gap if np.isfinite(gap) else self.gap_start,
                         float(d.max()) if d.size else 0.0], dtype=np.float64)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self.action_space.seed(seed)
        self.sim.restore(self.start_snapshot)
        self.p = self.start.copy()
        self.steps = 0
        self.refused = 0
        return self._obs(), {"time": self.sim.time, "refused_actions": 0, "gap": self.gap_start}

    def step(self, action):
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.size != 3 or not np.all(np.isfinite(a)):
            self.refused += 1
            a = np.zeros(3)
        a = np.clip(a, -1.0, 1.0)
        q = self.orientation
        per_tick = a * self.speed * self.sim.time_step
        for _ in range(self.ticks):
            self.p = np.clip(self.p + per_tick, self.lo, self.hi)
            self.sim.set_pose(self.tool, self.p.tolist(), q, 0.0)
            self.sim.step()
        self.steps += 1
        obs = self._obs()
        gap = self._gap()
        failed = (not np.isfinite(gap)) or float(np.linalg.norm(obs[3:6])) > self.max_tension
        reward = (self.gap_start - obs[6]) / self.gap_start - self.damage_weight * obs[7] - (10.0 if failed else 0.0)
        info = {"time": self.sim.time, "refused_actions": self.refused, "gap": gap}
        return obs, float(reward), bool(failed), self.steps >= self.max_steps, info
