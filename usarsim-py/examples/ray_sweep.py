"""A parameter sweep as Ray tasks: every (map, noise, seed) configuration flies one episode of
the Python waypoint controller; the results come back as one table.

Local (starts Ray on this machine):   python ray_sweep.py
On a Ray cluster:                     RAY_ADDRESS=ray://head-node:10001 python ray_sweep.py
  (or `ray job submit --working-dir . -- python ray_sweep.py`); every node needs the
  usarsim package installed (pip install <repo>/usarsim-py, or a runtime_env).
"""

import itertools
import os

import numpy as np
import ray


@ray.remote(num_cpus=1)
def episode(config: dict) -> dict:
    """One episode with one configuration; returns one table row."""
    import gymnasium

    import usarsim  # noqa: F401

    env = gymnasium.make("usarsim/Waypoints-v0", map=config["map"], noise=config["noise"],
                         start="random", max_steps=300)
    obs, _ = env.reset(seed=config["seed"])
    total, steps, done = 0.0, 0, False
    while not done:
        v, yaw = obs["waypoint"], obs["attitude"][2]
        c, s = np.cos(yaw), np.sin(yaw)
        action = np.clip([c * v[0] + s * v[1], -s * v[0] + c * v[1], -v[2], 0], -1, 1)
        obs, r, term, trunc, info = env.step(action.astype(np.float32))
        total, steps, done = total + r, steps + 1, term or trunc
    return {**config, "return": round(total, 3), "steps": steps,
            "waypoints": int(info["waypoints_reached"]), "node": os.uname().nodename}


def sweep(maps=("empty_room", "arena"), noises=(0.0, 0.05), seeds=range(3)) -> list:
    """Runs every configuration as a Ray task; returns the rows in configuration order."""
    configs = [{"map": m, "noise": n, "seed": s} for m, n, s in itertools.product(maps, noises, seeds)]
    return ray.get([episode.remote(c) for c in configs])


def table(rows: list) -> str:
    keys = list(rows[0])
    widths = [max(len(k), *(len(str(r[k])) for r in rows)) for k in keys]
    lines = ["  ".join(k.ljust(w) for k, w in zip(keys, widths))]
    lines += ["  ".join(str(r[k]).ljust(w) for k, w in zip(keys, widths)) for r in rows]
    return "\n".join(lines)


if __name__ == "__main__":
    # Connects to RAY_ADDRESS when set, else starts a local Ray.
    if os.environ.get("RAY_ADDRESS"):
        ray.init()
    else:
        ray.init(num_cpus=2, include_dashboard=False)
    print(table(sweep()))
