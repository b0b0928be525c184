"""The tasks (Waypoints, Hover) vectorized over many UAVs: observations, rewards, ends."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from ._core import LASER_BEAMS, SONARS
from ._maps import MapInfo

INF = np.float32(np.inf)

#: Observation keys and widths, in order.
FIELDS = {
    "position": 3,
    "velocity": 3,
    "attitude": 3,
    "angular_velocity": 3,
    "sonar": SONARS,
    "laser": LASER_BEAMS,
    "battery": 1,
    "waypoint": 3,
}

#: (low, high, width) of each observation; readings are clipped to them.
BOUNDS = {
    "position": (-1e4, 1e4, 3),
    "velocity": (-100.0, 100.0, 3),
    "attitude": (-np.pi, np.pi, 3),
    "angular_velocity": (-100.0, 100.0, 3),
    "sonar": (0.0, 5.0, SONARS),
    "laser": (0.0, 4.0, LASER_BEAMS),
    "battery": (0.0, 1.0, 1),
    "waypoint": (-2e4, 2e4, 3),
}

#: Reward for each waypoint reached.
WAYPOINT_BONUS = 10.0
#: Reward per control period in which the body was stopped by a wall, floor or UAV.
TOUCH_PENALTY = 1.0
CRASH_PENALTY = 100.0


def observation_space() -> spaces.Dict:
    """The observation space of one UAV."""

    def box(n, lo=-INF, hi=INF):
        return spaces.Box(lo, hi, (n,), np.float32)

    return spaces.Dict({k: box(BOUNDS[k][2], BOUNDS[k][0], BOUNDS[k][1]) for k in FIELDS})


def action_space() -> spaces.Box:
    """The action space of one UAV: forward, right, up, yaw rate, each in -1..1."""
    return spaces.Box(-1.0, 1.0, (4,), np.float32)


def _pose(value, map_info: MapInfo, what: str) -> np.ndarray:
    if isinstance(value, str):
        return map_info.start(value)
    a = np.asarray(value, dtype=np.float64).ravel()
    if a.shape not in ((3,), (4,)) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: expected a PlayerStart tag or finite (x, y, z[, yaw]), got {value!r}")
    return np.append(a, 0.0) if a.size == 3 else a


class Tasks:
    """Task state for `n` UAVs: targets, progress, step counts."""

    def __init__(self, task: str, n: int, map_info: MapInfo, *, start=None, waypoints=None,
                 n_waypoints: int = 3, waypoint_radius: float = 0.5, max_steps=None) -> None:
        if task not in ("waypoints", "hover"):
            raise ValueError(f"task: expected 'waypoints' or 'hover', got {task!r}")
        self.task, self.n, self.map = task, n, map_info
        self.start, self.waypoints = start, waypoints
        if not (isinstance(n_waypoints, (int, np.integer)) and n_waypoints >= 1):
            raise ValueError(f"n_waypoints: expected an integer >= 1, got {n_waypoints!r}")
        self.n_waypoints = int(n_waypoints)
        self.radius = float(waypoint_radius)
        self.max_steps = int(max_steps if max_steps is not None else (600 if task == "waypoints" else 200))
        if self.max_steps < 1:
            raise ValueError(f"max_steps: expected >= 1, got {max_steps!r}")
        if waypoints is not None:
            w = np.asarray(waypoints, dtype=np.float64)
            if w.ndim != 2 or w.shape[1] != 3 or len(w) == 0 or not np.all(np.isfinite(w)):
                raise ValueError(f"waypoints: expected finite shape (k, 3), got {np.shape(waypoints)}")
            self.n_waypoints = len(w)
        if start is not None and not (isinstance(start, str) and start == "random"):
            _pose(start, map_info, "start")  # checked now, not at the first reset
        w = self.n_waypoints if task == "waypoints" else 1
        self.targets = np.zeros((n, w, 3))
        self.hold_yaw = np.zeros(n)
        self.index = np.zeros(n, dtype=np.int64)
        self.steps = np.zeros(n, dtype=np.int64)
        self.prev = np.zeros(n)

    def default_start(self) -> np.ndarray:
        """The first PlayerStart, or (0, 0, -1)."""
        if self.map.starts:
            _, x, y, z, yaw = self.map.starts[0]
            return np.array([x, y, z, yaw])
        return np.array([0.0, 0.0, -1.0, 0.0])

    def new_starts(self, rng: np.random.Generator, rows, shared_world: bool, options=None,
                   poses=None) -> np.ndarray:
        """Chooses starts and targets for `rows`; returns their spawn poses (len(rows), 4).
        `poses` (one (x, y, z, yaw) per row) overrides the start option."""
        options = options or {}
        start = options.get("start", self.start)
        waypoints = options.get("waypoints", self.waypoints)
        rows = list(rows)
        if poses is not None:
            base = np.asarray(poses, dtype=np.float64)
        elif start is None and not shared_world:
            base = np.tile(self.default_start(), (len(rows), 1))
        elif start is None or (isinstance(start, str) and start == "random"):
            pts = self.map.sample(rng, len(rows))
            base = np.column_stack([pts, rng.uniform(-np.pi, np.pi, len(rows))])
        else:
            base = np.tile(_pose(start, self.map, "start"), (len(rows), 1))
        spawns = base.copy()
        for k, r in enumerate(rows):
            self.steps[r] = 0
            self.index[r] = 0
            if self.task == "hover":
                # Hold the start pose; spawn up to 1 m away from it (0.5 m vertically).
                self.targets[r, 0] = base[k, :3]
                self.hold_yaw[r] = base[k, 3]
                off = np.append(rng.uniform(-1.0, 1.0, 2), rng.uniform(-0.5, 0.5))
                cand = base[k, :3] + off
                if self.map.is_free(cand, 0.8) and cand[2] < -0.5:
                    spawns[k, :3] = cand
            elif waypoints is not None:
                self.targets[r] = np.asarray(waypoints, dtype=np.float64)
            else:
                self.targets[r] = self.map.sample(rng, self.n_waypoints, spacing=1.5,
                                                  near=base[k], radius=5.0)
        return spawns

    def _vector(self, raw) -> np.ndarray:
        tgt = self.targets[np.arange(self.n), np.minimum(self.index, self.targets.shape[1] - 1)]
        return tgt - raw["position"]

    def begin(self, raw, rows) -> None:
        """Remembers the starting distances of `rows` after a reset."""
        d = np.linalg.norm(self._vector(raw), axis=1)
        self.prev[list(rows)] = d[list(rows)]

    def observe(self, raw) -> dict:
        """The observation dict (float32 arrays, one row per UAV)."""
        values = {k: raw[k] for k in FIELDS if k != "waypoint"}
        values["attitude"] = (raw["attitude"] + np.pi) % (2 * np.pi) - np.pi
        values["waypoint"] = self._vector(raw)
        return {k: np.clip(v, BOUNDS[k][0], BOUNDS[k][1]).astype(np.float32) for k, v in values.items()}

    def reward(self, raw):
        """Rewards, terminated and truncated flags and info arrays after one step."""
        self.steps += 1
        touched = np.asarray(raw["touched"], dtype=bool)
        crashed = np.asarray(raw["crashed"], dtype=bool)
        dist = np.linalg.norm(self._vector(raw), axis=1)
        if self.task == "hover":
            yaw_err = np.abs((raw["attitude"][:, 2] - self.hold_yaw + np.pi) % (2 * np.pi) - np.pi)
            reward = -dist - 0.2 * yaw_err - TOUCH_PENALTY * touched
            terminated = np.zeros(self.n, dtype=bool)
            reached = np.zeros(self.n, dtype=bool)
        else:
            reward = self.prev - dist - TOUCH_PENALTY * touched
            reached = dist < self.radius
            reward = reward + WAYPOINT_BONUS * reached
            self.index = self.index + reached
            terminated = self.index >= self.targets.shape[1]
            dist = np.linalg.norm(self._vector(raw), axis=1)
        self.prev = dist
        # A crash (robots with physics: docs/quadrotor.md) ends the episode with a penalty.
        reward = reward - CRASH_PENALTY * crashed
        terminated = terminated | crashed
        truncated = ~terminated & ((self.steps >= self.max_steps) | (raw["battery"][:, 0] <= 0.0))
        return reward, terminated, truncated, {"touched": touched, "crashed": crashed, "reached": reached,
                                               "waypoints_reached": self.index.copy()}
