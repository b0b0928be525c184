"""Soak of the vector env (issue #26): 1M UAV-steps with the resident memory sampled and
printed; memory must stay flat (within ±10 % of its level after warm-up). Not run in CI.

    python benchmarks/soak.py [uav_steps [num_envs [sample_every]]]

Defaults: 1,000,000 UAV-steps (sub-environment steps) of ``usarsim.vector_env(64)`` with
full observations and random actions, episodes ending and autoresetting as they come; the
resident memory (VmRSS) is sampled every 500 vector steps (32,000 UAV-steps). Warm-up is the
first 10 % of the steps; the reference is the first sample after it. Exits 1 if a later
sample is more than 10 % away from the reference.
"""

import sys
import time

import numpy as np

import usarsim


def rss_mib(field="VmRSS"):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) / 1024
    return float("nan")


def main():
    total = int(float(sys.argv[1])) if len(sys.argv) > 1 else 1_000_000
    num = int(sys.argv[2]) if len(sys.argv) > 2 else 64
    every = int(sys.argv[3]) if len(sys.argv) > 3 else 500
    venv = usarsim.vector_env(num)
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = [rng.uniform(-1, 1, (num, 4)).astype(np.float32) for _ in range(16)]
    steps = (total + num - 1) // num
    warmup = steps // 10
    reference = None
    worst = 0.0
    episodes = 0
    print(f"{num} envs, {steps} vector steps ({steps * num:,} UAV-steps), RSS every {every}")
    print(f"{'UAV-steps':>12} {'RSS MiB':>9} {'vs ref':>8} {'episodes':>9} {'UAV-steps/s':>12}")
    start = last = time.perf_counter()
    last_step = 0
    for i in range(1, steps + 1):
        _, _, terminated, truncated, _ = venv.step(actions[i % 16])
        episodes += int(np.count_nonzero(terminated | truncated))
        if i % every and i != steps:
            continue
        now, rss = time.perf_counter(), rss_mib()
        rate = (i - last_step) * num / max(now - last, 1e-9)
        last, last_step = now, i
        if reference is None and i >= warmup:
            reference = rss
        change = "" if reference is None else f"{(rss / reference - 1) * 100:+.1f} %"
        if reference is not None:
            worst = max(worst, abs(rss / reference - 1))
        print(f"{i * num:>12,} {rss:>9.1f} {change:>8} {episodes:>9} {rate:>12,.0f}", flush=True)
    venv.close()
    seconds = time.perf_counter() - start
    print(f"{steps * num:,} UAV-steps in {seconds:.0f} s ({steps * num / seconds:,.0f}/s), "
          f"{episodes} episodes; peak RSS {rss_mib('VmHWM'):.1f} MiB; "
          f"largest change after warm-up {worst * 100:.1f} %")
    if worst > 0.10:
        print("memory is not flat (more than 10 % away from its level after warm-up)")
        sys.exit(1)
    print("memory flat (within 10 % after warm-up)")


if __name__ == "__main__":
    main()
