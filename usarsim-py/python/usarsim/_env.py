"""The Gymnasium environment, the vector environment and the PettingZoo environment."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _core
from ._maps import MapInfo
from ._render import TopView
from ._task import Tasks, action_space, observation_space


def _robot(name: str) -> str:
    return _core.qualified_class(name)


def _actions(action, n: int) -> np.ndarray:
    """Actions as float64 (n, 4); ValueError naming the problem otherwise."""
    try:
        a = np.asarray(action, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"action: not a numeric array: {e}") from None
    want = (4,) if n == 1 else (n, 4)
    if a.shape != want and a.shape != (n, 4):
        raise ValueError(f"action: expected shape {want}, got {a.shape}")
    a = a.reshape(n, 4)
    bad = np.argwhere(~np.isfinite(a))
    if len(bad):
        r, c = bad[0]
        raise ValueError(f"action: row {r}, component {c} is not finite ({a[r, c]})")
    return a


def _seed(rng: np.random.Generator) -> int:
    return int(rng.integers(0, 2**63 - 1))


class UsarsimEnv(gym.Env):
    """One stsAirRobot in a map (`usarsim/Waypoints-v0`, `usarsim/Hover-v0`).

    Keyword options: ``map`` (embedded name or map file), ``robot``, ``start`` (a PlayerStart
    tag, ``(x, y, z[, yaw])`` or ``"random"``), ``waypoints`` (``(k, 3)`` or None for
    seeded random ones), ``n_waypoints``, ``period`` (control period, s), ``noise`` (sensor
    noise std for every part), ``max_steps``, ``server`` (``"host:port"`` to fly a running
    usar-server or USARSim instead of the in-process world), ``render_mode``.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, task: str = "waypoints", *, map: str = "empty_room", robot: str = "stsAirRobot",
                 start=None, waypoints=None, n_waypoints: int = 3, waypoint_radius: float = 0.5,
                 period: float = 0.1, noise: float | None = None, max_steps: int | None = None,
                 server: str | None = None, render_mode: str | None = None) -> None:
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode: expected None or 'rgb_array', got {render_mode!r}")
        self.render_mode = render_mode
        self.observation_space = observation_space()
        self.action_space = action_space()
        self._robot, self._period, self._server = _robot(robot), float(period), server
        # The in-process world (also the map geometry for a remote server running the same map).
        self._batch = _core.Batch(map, self._robot, [0], _first(map), 1, period, noise)
        self.map = MapInfo(self._batch)
        self._tasks = Tasks(task, 1, self.map, start=start, waypoints=waypoints, n_waypoints=n_waypoints,
                            waypoint_radius=waypoint_radius, max_steps=max_steps)
        self._remote = None
        self._view = None
        self._trail: list = []
        self._raw = None

    def _observe(self):
        self._raw = (self._remote or self._batch).observe()
        return self._raw

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        starts = self._tasks.new_starts(self.np_random, [0], False, options)
        if self._server is None:
            self._batch.reset_world(0, _seed(self.np_random), starts)
        else:
            if self._remote is not None:
                self._remote.close()
            self._remote = _core.Remote(self._server, self._robot, list(starts[0]), self._period)
        raw = self._observe()
        self._tasks.begin(raw, [0])
        self._trail = [raw["position"][0, :2].copy()]
        return {k: v[0] for k, v in self._tasks.observe(raw).items()}, {"lockstep": self._remote.lockstep if self._remote else True}

    def step(self, action):
        if self._raw is None:
            raise ValueError("step: call reset() first")
        a = _actions(action, 1)
        if self._remote is not None:
            self._remote.step(list(a[0]))
        else:
            self._batch.step(a)
        raw = self._observe()
        self._trail.append(raw["position"][0, :2].copy())
        reward, term, trunc, info = self._tasks.reward(raw)
        obs = {k: v[0] for k, v in self._tasks.observe(raw).items()}
        return obs, float(reward[0]), bool(term[0]), bool(trunc[0]), {k: v[0] for k, v in info.items()}

    def render(self):
        if self.render_mode != "rgb_array" or self._raw is None:
            return None
        if self._view is None:
            self._view = TopView(self.map)
        raw = self._raw
        return self._view.draw(raw["position"], raw["attitude"][:, 2], raw["laser"], [self._trail],
                               self._tasks.targets[:, self._tasks.index[0]:])

    def close(self):
        if self._remote is not None:
            self._remote.close()
            self._remote = None


def _first(map_name: str) -> np.ndarray:
    """A spawn pose for the world used before the first reset: the map's first start."""
    probe = _core.Batch(map_name, "USARBot.AirRobot", [0], np.array([[0.0, 0.0, -1000.0, 0.0]]))
    starts = probe.start_poses()
    if starts:
        _, x, y, z, yaw = starts[0]
        return np.array([[x, y, z, yaw]])
    return np.array([[0.0, 0.0, -1.0, 0.0]])


class UsarsimVectorEnv(VectorEnv):
    """`num_envs` independent worlds with one UAV each, stepped by Rust in one call.

    Same options as :class:`UsarsimEnv` (no ``server``). Autoreset: next step (Gymnasium's
    default): the step after an episode ends resets that sub-environment and ignores its action.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int, task: str = "waypoints", *, map: str = "empty_room",
                 robot: str = "stsAirRobot", start=None, waypoints=None, n_waypoints: int = 3,
                 waypoint_radius: float = 0.5, period: float = 0.1, noise: float | None = None,
                 max_steps: int | None = None) -> None:
        if not (isinstance(num_envs, (int, np.integer)) and num_envs >= 1):
            raise ValueError(f"num_envs: expected an integer >= 1, got {num_envs!r}")
        self.num_envs = int(num_envs)
        self.single_observation_space = observation_space()
        self.single_action_space = action_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        first = _first(map)
        self._batch = _core.Batch(map, _robot(robot), [0] * self.num_envs, np.repeat(first, self.num_envs, 0),
                                  1, period, noise)
        self.map = MapInfo(self._batch)
        self._tasks = Tasks(task, self.num_envs, self.map, start=start, waypoints=waypoints,
                            n_waypoints=n_waypoints, waypoint_radius=waypoint_radius, max_steps=max_steps)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        if seed is not None:
            self._rngs = [np.random.default_rng([int(seed), i]) for i in range(self.num_envs)]
        elif not hasattr(self, "_rngs"):
            self._rngs = [np.random.default_rng(_seed(self.np_random) + i) for i in range(self.num_envs)]
        for i in range(self.num_envs):
            self._reset_one(i, options)
        self._autoreset[:] = False
        raw = self._batch.observe()
        self._tasks.begin(raw, range(self.num_envs))
        return self._tasks.observe(raw), {}

    def _reset_one(self, i, options=None):
        rng = self._rngs[i]
        starts = self._tasks.new_starts(rng, [i], False, options)
        self._batch.reset_world(i, _seed(rng), starts)

    def step(self, actions):
        a = _actions(actions, self.num_envs)
        done = np.flatnonzero(self._autoreset)
        a[done] = 0.0
        self._batch.step(a)
        for i in done:
            self._reset_one(int(i))
        raw = self._batch.observe()
        reward, term, trunc, info = self._tasks.reward(raw)
        if len(done):
            self._tasks.begin(raw, done)
            reward[done] = 0.0
            term[done] = False
            trunc[done] = False
        self._autoreset = term | trunc
        return self._tasks.observe(raw), reward, term, trunc, info


def _register() -> None:
    for env_id, task in (("usarsim/Waypoints-v0", "waypoints"), ("usarsim/Hover-v0", "hover")):
        if env_id not in gym.registry:
            gym.register(env_id, entry_point="usarsim._env:UsarsimEnv", kwargs={"task": task},
                         vector_entry_point="usarsim._env:UsarsimVectorEnv")
