"""UAV-steps per second and per CPU-second (figures for BENCHMARKS.md).

    python benchmarks/steps_per_second.py [seconds per case]

1 UAV: gymnasium.make("usarsim/Waypoints-v0") stepped from Python (with Gymnasium's
wrappers, as users run it). N UAVs: usarsim.vector_env(N), one Rust call per step; a UAV-step
is one UAV advanced one control period (0.1 s simulated, 20 physics ticks). "full": the
stsAirRobot with every sensor (228-beam laser, 10 sonars) and the Dict observation; "state":
``state_only=True, flat=True`` (no range sensors; one float32 Box). Random actions; episodes
end and autoreset (NEXT_STEP) as they come. "autoreset step": one step in which every
sub-environment resets (episodes of 1 step), against a normal step, full and state-only (a
reset flies the world until every sensor has read once: three control periods with the 0.3 s
laser, one without the range sensors).

Per CPU-second is the process's CPU time (user + system, all threads): on a machine shared
with other work it is the fairer figure; wall-clock UAV-steps/s depends on the free cores.
"""

import os
import statistics
import sys
import time

import gymnasium
import numpy as np

import usarsim


def clocks():
    # process_time: user + system of every thread, at nanosecond resolution (os.times() counts
    # in 10 ms ticks, too coarse for one step).
    return time.perf_counter(), time.process_time()


def single(seconds):
    env = gymnasium.make("usarsim/Waypoints-v0")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    n, (w0, c0) = 0, clocks()
    while clocks()[0] - w0 < seconds:
        _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
        n += 1
        if term or trunc:
            env.reset()
    w1, c1 = clocks()
    return n / (w1 - w0), n / max(c1 - c0, 1e-9)


def vector(num, seconds, **options):
    venv = usarsim.vector_env(num, **options)
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = [rng.uniform(-1, 1, (num, 4)) for _ in range(8)]
    n, (w0, c0) = 0, clocks()
    while clocks()[0] - w0 < seconds or n == 0:
        venv.step(actions[n % 8])
        n += 1
    w1, c1 = clocks()
    return n * num / (w1 - w0), n * num / max(c1 - c0, 1e-9)


def autoreset(num, repeats=5, **options):
    """(wall, CPU) seconds of a normal step and of a step where all `num` sub-envs reset
    (medians)."""
    venv = usarsim.vector_env(num, "hover", max_steps=1, **options)
    venv.reset(seed=0)
    a = np.zeros((num, 4))
    normal, resetting = [], []
    for _ in range(repeats):
        for record in (normal, resetting):  # max_steps=1 ends every episode: a normal step,
            w0, c0 = clocks()  # then (NEXT_STEP) a step where every sub-env resets
            venv.step(a)
            w1, c1 = clocks()
            record.append((w1 - w0, c1 - c0))
    med = lambda xs, i: statistics.median(x[i] for x in xs)  # noqa: E731
    return (med(normal, 0), med(normal, 1)), (med(resetting, 0), med(resetting, 1))


if __name__ == "__main__":
    seconds = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0
    print(f"cores: {os.cpu_count()}, load average {os.getloadavg()[0]:.1f} at the start")
    cases = [("1 UAV (gymnasium.make), full", lambda: single(seconds))]
    for n in (256, 1024):
        cases.append((f"vector env, {n} UAVs, full", lambda n=n: vector(n, seconds)))
        cases.append((f"vector env, {n} UAVs, state", lambda n=n: vector(n, seconds, state_only=True, flat=True)))
    for name, fn in cases:
        wall, cpu = fn()
        print(f"{name:34s} {wall:10.0f} UAV-steps/s   {cpu:10.0f} per CPU-second")
    for n in (256, 1024):
        for kind, options in (("full", {}), ("state", {"state_only": True, "flat": True})):
            (nw, nc), (rw, rc) = autoreset(n, **options)
            print(f"autoreset, {n:4d} UAVs, {kind}: normal step {nw * 1e3:6.1f} ms ({nc * 1e3:5.1f} CPU), "
                  f"resetting all {rw * 1e3:6.1f} ms ({rc * 1e3:5.1f} CPU): {rw / nw:.2f}x wall, {rc / nc:.2f}x CPU")
