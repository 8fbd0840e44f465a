"""A Gymnasium environment over stroma.Simulation (docs/PYTHON.md, "A Gymnasium environment").

ProbePressEnv: a spherical probe above the liver must press it to a target force without
damaging it. The scenario is scenarios/regression/liver_probe_damage.yaml (SOFA's liver in its
mesh units, a von Mises damage model); its probe script is overridden by the actions.

    action       float32[1] in [-1, 1]: the probe's target height, from the top of its travel (-1:
                 the start, above the tissue) to its bottom (+1: `depth` below the tissue's top
                 under the probe); each action moves the probe toward the target at most at the
                 tool's speed limit. A uniform random policy therefore touches the tissue within
                 tens of actions. `speed` (default 2 units/s, at most the tool's max_speed).
    observation  float64[4]: probe height above its start, the tissue's force on it along +y (N),
                 the largest element damage, the target force
    reward       -|F - target| / target per action, -10 when an element is damaged
    terminated   an element reached "damaged" (the damage model's onset)
    truncated    after max_steps actions
Each action lasts `ticks_per_action` engine ticks (1 ms each).

Invalid actions follow the tool's `on_invalid` policy, as every front end's commands do: an action
outside [-1, 1] is clipped into it under `clamp` and refused under `reject` (the probe holds its
height); a non-finite action is always refused. A refused action is counted
(`info["refused_actions"]`), never applied: the observations stay finite.

With gymnasium installed, ProbePressEnv is a gymnasium.Env and its spaces gymnasium.spaces.Box
(it passes gymnasium.utils.env_checker.check_env); without it, the same API with a small Box of
the same interface (low, high, shape, dtype, sample, contains, seed).
"""
import os

import numpy as np

from ._stroma import Simulation

#: The scenarios shipped with the package (a copy of the source tree's scenarios/ files it uses).
DATA_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "data")

try:  # gymnasium is optional: the environment follows its API either way
    import gymnasium as _gym
    from gymnasium import spaces as _spaces

    _EnvBase = _gym.Env
    Box = _spaces.Box
except ImportError:  # pragma: no cover - exercised where gymnasium is absent
    _gym = None

    class _EnvBase:
        """The part of gymnasium.Env this environment needs."""

        metadata = {"render_modes": []}
        render_mode = None
        np_random = None

        def reset(self, *, seed=None, options=None):
            if seed is not None or self.np_random is None:
                self.np_random = np.random.default_rng(seed)

        def close(self):
            pass

        @property
        def unwrapped(self):
            return self

    class Box:
        """A box in R^n (gymnasium.spaces.Box's interface: low, high, shape, dtype, sample,
        contains, seed)."""

        def __init__(self, low, high, shape=None, dtype=np.float32):
            self.dtype = np.dtype(dtype)
            shape = tuple(shape) if shape is not None else np.shape(low)
            self.shape = shape
            self.low = np.broadcast_to(np.asarray(low, dtype=self.dtype), shape).copy()
            self.high = np.broadcast_to(np.asarray(high, dtype=self.dtype), shape).copy()
            self._rng = np.random.default_rng()

        def seed(self, seed=None):
            self._rng = np.random.default_rng(seed)
            return [seed]

        def sample(self):
            lo = np.where(np.isfinite(self.low), self.low, -1.0)
            hi = np.where(np.isfinite(self.high), self.high, 1.0)
            return self._rng.uniform(lo, hi).astype(self.dtype)

        def contains(self, x):
            x = np.asarray(x)
            return x.shape == self.shape and bool(np.all(x >= self.low) and np.all(x <= self.high))

        def __repr__(self):
            return f"Box({self.low}, {self.high}, {self.shape}, {self.dtype})"


class ProbePressEnv(_EnvBase):
    metadata = {"render_modes": []}

    def __init__(self, scenario=None, target_force=1.0, ticks_per_action=10, max_steps=300, start=(-1.5, 6.0, 0.5),
                 depth=1.0, speed=2.0, render_mode=None):
        if render_mode is not None:
            raise ValueError("ProbePressEnv draws nothing (render_mode must be None; use stroma render or write_vtu)")
        self.render_mode = None
        if scenario is None:
            scenario = os.path.join(DATA_DIR, "regression", "liver_probe_damage.yaml")
        self.sim = Simulation(scenario)
        self.target = float(target_force)
        self.ticks = int(ticks_per_action)
        self.max_steps = int(max_steps)
        self.start = np.array(start, dtype=float)
        tool = self.sim.tools[0]
        # The probe's speed toward its target: `speed` (units/s), never above the tool's max_speed.
        self.max_speed = min(float(speed), float(tool["max_speed"]))
        self.clamp = tool["on_invalid"] == "clamp"
        lo, hi = np.array(tool["workspace"]["min"]), np.array(tool["workspace"]["max"])
        if np.any(self.start < lo) or np.any(self.start > hi):
            raise ValueError(f"start {tuple(self.start)} is outside the probe's workspace {tuple(lo)}..{tuple(hi)}")
        # The travel: from the start down to `depth` below the tissue's top under the probe (the
        # highest rest node within the tip radius of its column), kept inside the workspace.
        x = self.sim.positions
        column = np.hypot(x[:, 0] - self.start[0], x[:, 2] - self.start[2]) <= max(tool["radius"], 1e-9) * 2
        top = x[column, 1].max() if column.any() else x[:, 1].max()
        self.y_top = self.start[1]
        self.y_bottom = max(min(top - float(depth), self.y_top), lo[1])
        self.action_space = Box(low=-1.0, high=1.0, shape=(1,), dtype=np.float32)
        self.observation_space = Box(low=np.array([lo[1] - self.start[1], -np.inf, 0.0, 0.0]),
                                     high=np.array([hi[1] - self.start[1], np.inf, 1.0, np.inf]), dtype=np.float64)
        self.y = self.y_top
        self.steps = 0
        self.refused = 0

    def _obs(self):
        fb = self.sim.feedback(0)
        d = self.sim.damage
        return np.array([self.y - self.start[1], fb["force"][1], float(d.max()) if d.size else 0.0, self.target],
                        dtype=np.float64)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self.action_space.seed(seed)
        if options and "target_force" in options:
            self.target = float(options["target_force"])
        self.sim.reset()
        self.y = self.y_top
        self.steps = 0
        self.refused = 0
        self.sim.set_pose(0, [self.start[0], self.y, self.start[2]])
        return self._obs(), {"time": self.sim.time, "refused_actions": 0}

    def target_height(self, action):
        """The probe height an action asks for, or None when the action is refused (see above)."""
        a = np.asarray(action, dtype=np.float64).reshape(-1)
        if a.size != 1 or not np.isfinite(a[0]):
            return None
        u = a[0]
        if u < -1.0 or u > 1.0:
            if not self.clamp:
                return None
            u = min(max(u, -1.0), 1.0)
        return self.y_top + 0.5 * (u + 1.0) * (self.y_bottom - self.y_top)

    def step(self, action):
        target = self.target_height(action)
        if target is None:
            self.refused += 1
            target = self.y  # refused: the probe holds its height
        per_tick = self.max_speed * self.sim.time_step * 0.999  # inside the tool's speed check
        for _ in range(self.ticks):
            self.y += float(np.clip(target - self.y, -per_tick, per_tick))
            self.sim.set_pose(0, [self.start[0], self.y, self.start[2]])
            self.sim.step()
        self.steps += 1
        obs = self._obs()
        damaged = self.sim.damage_counts[1] > 0
        reward = -abs(obs[1] - self.target) / self.target - (10.0 if damaged else 0.0)
        info = {"time": self.sim.time, "refused_actions": self.refused}
        return obs, float(reward), bool(damaged), self.steps >= self.max_steps, info
