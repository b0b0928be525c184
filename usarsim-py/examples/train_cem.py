"""Learns to hover with the cross-entropy method: a linear policy in numpy, many UAVs per
generation stepped by Rust in one call (usarsim.vector_env).

    python train_cem.py [generations]
"""

import sys

import numpy as np

import usarsim

FEATURES = 7  # waypoint vector (3), velocity (3), bias


def features(obs):
    return np.hstack([obs["waypoint"], obs["velocity"], np.ones((len(obs["waypoint"]), 1))])


def evaluate(venv, weights, seed, steps):
    """Mean return of each policy (one UAV per weight matrix) over one episode."""
    obs, _ = venv.reset(seed=seed)
    total = np.zeros(len(weights))
    for _ in range(steps):
        x = features(obs)
        actions = np.tanh(np.einsum("nf,nfa->na", x, weights))
        obs, reward, *_ = venv.step(actions)
        total += reward
    return total


def train(generations=8, population=32, elite=6, steps=40, seed=0, verbose=True):
    """Returns the mean return of the policy mean before and after training."""
    rng = np.random.default_rng(seed)
    venv = usarsim.vector_env(population, "hover", max_steps=steps)
    mean = np.zeros((FEATURES, 4))
    std = np.full((FEATURES, 4), 0.5)

    def score(m):
        return evaluate(venv, np.repeat(m[None], population, 0), 1000, steps).mean()

    before = score(mean)
    for g in range(generations):
        samples = mean + std * rng.standard_normal((population, FEATURES, 4))
        returns = evaluate(venv, samples, g, steps)
        best = samples[np.argsort(returns)[-elite:]]
        mean, std = best.mean(axis=0), best.std(axis=0) + 0.02
        if verbose:
            print(f"generation {g}: mean return {returns.mean():8.2f}, best {returns.max():8.2f}")
    after = score(mean)
    if verbose:
        print(f"policy mean: return {before:.2f} before, {after:.2f} after training")
    return before, after


if __name__ == "__main__":
    train(int(sys.argv[1]) if len(sys.argv) > 1 else 8)
