"""A waypoint controller in Python, two ways:

1. as a Gymnasium policy on usarsim/Waypoints-v0 (in-process, lockstep);
2. as a usarsim.Agent flown by ucc-client's runner (missions, logs, trajectories, pictures)
   against a usar-server started in this process, or a running one: pass host:port.
"""

import sys

import gymnasium
import numpy as np

import usarsim


def policy(obs) -> np.ndarray:
    """Turn the world-frame vector to the waypoint into the heading frame; fly at it."""
    v, yaw = obs["waypoint"], obs["attitude"][2]
    c, s = np.cos(yaw), np.sin(yaw)
    forward, right = c * v[0] + s * v[1], -s * v[0] + c * v[1]
    return np.clip([forward, right, -v[2], 0.0], -1, 1).astype(np.float32)


class WaypointAgent(usarsim.Agent):
    """The same controller for ucc-client's runner: state in, usarsim.Command out."""

    def step(self, state):
        if state.target is None:  # a Hover mission: hold still
            return usarsim.Command()
        v = np.subtract(state.target, state.position)
        yaw = state.attitude[2]
        c, s = np.cos(yaw), np.sin(yaw)
        f, r, u = np.clip([c * v[0] + s * v[1], -s * v[0] + c * v[1], -v[2]], -1, 1)
        return usarsim.Command(forward=f, right=r, up=u)


env = gymnasium.make("usarsim/Waypoints-v0")
obs, _ = env.reset(seed=2)
total, done, t = 0.0, False, 0
while not done:
    obs, r, term, trunc, info = env.step(policy(obs))
    total, done, t = total + r, term or trunc, t + 1
print(f"gymnasium: {info['waypoints_reached']} waypoints in {t} steps, return {total:.1f}")

server = sys.argv[1] if len(sys.argv) > 1 else None
result = usarsim.fly(WaypointAgent, [(3, 0, -2), (3, 3, -2.5), {"hover": 2.0}, (0, 0, -1)],
                     server=server, iterations=2, log_dir="waypoint-controller-output")
print(f"runner: {result['completed']} of {len(result['iterations'])} iterations completed; "
      f"files in waypoint-controller-output/")
