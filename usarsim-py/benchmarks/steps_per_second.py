"""Environment steps per second with the full sensor suite (figures for BENCHMARKS.md).

    python benchmarks/steps_per_second.py [runs]

1 UAV: gymnasium.make("usarsim/Waypoints-v0") stepped from Python (with Gymnasium's
wrappers, as users run it). N UAVs: usarsim.vector_env(N), one Rust call per step; a UAV-step
is one UAV advanced one control period (0.1 s simulated, 20 physics ticks, every sensor).
Random actions; episodes reset as they end.
"""

import statistics
import sys
import time

import gymnasium
import numpy as np

import usarsim


def single(seconds=3.0):
    env = gymnasium.make("usarsim/Waypoints-v0")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
        n += 1
        if term or trunc:
            env.reset()
    return n / (time.perf_counter() - start)


def vector(num, seconds=3.0):
    venv = usarsim.vector_env(num)
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds or n == 0:
        venv.step(rng.uniform(-1, 1, (num, 4)))
        n += 1
    return n * num / (time.perf_counter() - start)


if __name__ == "__main__":
    runs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    cases = [("1 UAV (gymnasium.make)", single)] + [
        (f"vector env, {n} UAVs", lambda n=n: vector(n)) for n in (16, 256, 1024)]
    for name, fn in cases:
        figures = sorted(fn() for _ in range(runs))
        print(f"{name:28s} UAV-steps/s  min {figures[0]:9.0f}  median {statistics.median(figures):9.0f}  "
              f"max {figures[-1]:9.0f}")
