"""Improve on a scenario's baseline agent with a simple learning method.

The `tracking` scenario's baseline, the `target-follow` team agent, flies over where it last
saw the target (moved on at its estimated velocity). Here a two-gain policy learns to do
better with the cross-entropy method (CEM):

    command = clip((k_p * goal + k_f * target_velocity) / top_speed)

where `goal` is the target relative to the UAV (the observation's goal) and the target's
velocity is estimated from two observations. The score is the episode's mean tracking
error (metres, lower is better), measured by the scenario against ground truth.

    python examples/scenario_cem.py [--iterations 8] [--population 10]
"""

from __future__ import annotations

import argparse

import numpy as np

import usarsim

TOP_SPEED = 2.0  # m/s: the stsAirRobot's


def episode(gains, seed: int = 1) -> float:
    """Mean tracking error of one episode flown with `gains` = (k_p, k_f)."""
    kp, kf = gains
    env = usarsim.ScenarioEnv("tracking", uav=0)
    obs, _ = env.reset(seed=seed)
    period = 0.1
    prev_target = None
    done, info = False, {}
    while not done:
        pos, vel, goal = obs[0:3], obs[3:6], obs[11:14]
        target = pos + goal
        v_target = np.zeros(3) if prev_target is None else (target - prev_target) / period
        prev_target = target
        # Heading stays north (yaw 0): world x is forward, y is right.
        cmd = (kp * goal[:2] + kf * v_target[:2]) / TOP_SPEED
        action = np.clip([cmd[0], cmd[1], -goal[2], 0.0], -1.0, 1.0)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    return info["metrics"]["tracking_error_m"]


def baseline(seed: int = 1) -> float:
    """The `target-follow` agent's mean tracking error on the same episode."""
    sim = usarsim._core.Scenario("tracking", [])
    sim.reset(seed)
    while not sim.step([]):
        pass
    return sim.metrics()["tracking_error_m"]


def cem(iterations: int, population: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    mean, std = np.array([1.0, 0.0]), np.array([1.0, 0.5])
    for i in range(iterations):
        samples = np.abs(mean + std * rng.standard_normal((population, 2)))
        errors = np.array([episode(s) for s in samples])
        elite = samples[np.argsort(errors)[: max(2, population // 4)]]
        mean, std = elite.mean(axis=0), elite.std(axis=0) + 0.02
        print(f"iteration {i + 1}: best error {errors.min():.3f} m, mean gains k_p={mean[0]:.2f} k_f={mean[1]:.2f}")
    return mean


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--iterations", type=int, default=8)
    parser.add_argument("--population", type=int, default=10)
    args = parser.parse_args()
    base = baseline()
    print(f"baseline target-follow agent: mean tracking error {base:.3f} m")
    gains = cem(args.iterations, args.population)
    learned = episode(gains)
    print(f"learned gains k_p={gains[0]:.2f} k_f={gains[1]:.2f}: mean tracking error {learned:.3f} m "
          f"({'better' if learned < base else 'not better'} than the baseline's {base:.3f} m)")


if __name__ == "__main__":
    main()
