"""Presses the liver to a target force with a proportional controller on ProbePressEnv
(docs/PYTHON.md). Run: PYTHONPATH=build/python python3 examples/python/press_to_force.py"""
import sys

from stroma.env import ProbePressEnv


def main(target=1.0, gain=0.05, approach=1.0):
    env = ProbePressEnv(target_force=target)
    obs, _ = env.reset()
    total = 0.0
    for _ in range(env.max_steps):
        # Down at `approach` until the probe touches, then speed ∝ the force error (units/s per
        # unit of force: the contact is stiff, a large gain makes the press oscillate).
        action = -approach if obs[1] <= 0 else -gain * (target - obs[1])
        obs, reward, terminated, truncated, info = env.step([action])
        total += reward
        if terminated or truncated:
            break
    print(f"t = {info['time']:.2f} s: force {obs[1]:.3f} (target {target}), depth {-obs[0]:.3f}, "
          f"max damage {obs[2]:.3f}, return {total:.1f}, {'damaged' if terminated else 'intact'}")
    return obs, terminated


if __name__ == "__main__":
    obs, damaged = main(*(float(a) for a in sys.argv[1:]))
    sys.exit(1 if damaged else 0)
