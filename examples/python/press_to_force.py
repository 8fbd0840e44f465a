"""Presses the liver to a target force with an integral controller on ProbePressEnv
(docs/PYTHON.md). Run: PYTHONPATH=build/python python3 examples/python/press_to_force.py"""
import sys

import numpy as np

from stroma.env import ProbePressEnv


def main(target=1.0, gain=1e-3, approach=0.02):
    env = ProbePressEnv(target_force=target)
    obs, _ = env.reset(seed=0)
    total = 0.0
    a = -1.0  # the action is the target height: -1 the start, +1 the bottom of the travel
    for _ in range(env.max_steps):
        # Down by `approach` per action until the probe touches, then by the force error (the
        # contact is stiff: a large gain makes the press oscillate).
        a = float(np.clip(a + (approach if obs[1] <= 0 else gain * (target - obs[1])), -1.0, 1.0))
        obs, reward, terminated, truncated, info = env.step([a])
        total += reward
        if terminated or truncated:
            break
    print(f"t = {info['time']:.2f} s: force {obs[1]:.3f} (target {target}), depth {-obs[0]:.3f}, "
          f"max damage {obs[2]:.3f}, return {total:.1f}, {'damaged' if terminated else 'intact'}")
    return obs, terminated


if __name__ == "__main__":
    obs, damaged = main(*(float(a) for a in sys.argv[1:]))
    sys.exit(1 if damaged else 0)
