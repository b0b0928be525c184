"""PettingZoo ParallelEnv: N UAVs in one world, each seeing the others in its sensors."""

from __future__ import annotations

import functools

import numpy as np

from . import _core
from gymnasium.error import ClosedEnvironmentError, ResetNeeded

from ._env import Replay, _actions, _first, _rates, _render_mode, _rng, _robot, _seed
from ._maps import MapInfo
from ._render import TopView
from ._task import (Tasks, action_space, add_extras, camera_kinds, image_size, observation_space, with_extras,
                    with_rotor_speeds)

try:
    from pettingzoo import ParallelEnv
except ImportError:  # pragma: no cover - pettingzoo is an optional extra
    ParallelEnv = object


class MultiUavEnv(Replay, ParallelEnv):
    """N stsAirRobots in one world, agents ``uav_0`` ... ``uav_{n-1}``.

    Each agent has its own task (its waypoints, or its pose to hold); starts are seeded
    random free places 1.2 m apart unless ``start`` lists one pose per UAV. An agent that has
    finished is removed from ``agents`` and hovers in place (still an obstacle to the others).
    Opt-in observations: ``camera`` (``"depth"``, ``"rgb"``, ``"rgbd"``) of ``camera_size``,
    and with ``radio`` the signal to every agent (``signal``, dBm, in ``possible_agents``
    order; 0 for itself; the link breaks below -93). Faults, randomisation and rotor speeds:
    :meth:`configure`.
    """

    metadata = {"render_modes": ["rgb_array"], "name": "usarsim_multi_uav_v0", "render_fps": 10}

    def __init__(self, n: int = 2, task: str = "waypoints", *, map: str = "empty_room",
                 robot: str = "stsAirRobot", starts=None, n_waypoints: int = 3,
                 waypoint_radius: float = 0.5, period: float = 0.1, noise: float | None = None,
                 max_steps: int | None = None, render_mode: str | None = None, state_only: bool = False,
                 flat: bool = False, action_mode: str = "velocity", camera: str | None = None,
                 camera_size=(64, 64), radio: bool = False, physics_rate: float | None = None,
                 sensor_rates: dict | None = None, robots: str | None = None) -> None:
        if ParallelEnv is object:
            raise ImportError("usarsim.multi_uav needs pettingzoo: pip install pettingzoo")
        if not (isinstance(n, (int, np.integer)) and not isinstance(n, bool) and n >= 1):
            raise ValueError(f"n: expected an integer >= 1, got {n!r}")
        self._recipe = dict(n=n, task=task, map=map, robot=robot, starts=starts, n_waypoints=n_waypoints,
                            waypoint_radius=waypoint_radius, period=period, noise=noise, max_steps=max_steps,
                            render_mode=render_mode, state_only=state_only, flat=flat, action_mode=action_mode,
                            camera=camera, camera_size=camera_size, radio=radio, physics_rate=physics_rate,
                            sensor_rates=sensor_rates, robots=robots)
        self.n = int(n)
        self.render_mode = _render_mode(render_mode)
        self.possible_agents = [f"uav_{i}" for i in range(self.n)]
        self.agents = []
        first = _first(map)
        rates = _rates(physics_rate, sensor_rates, robots)
        probe = _core.Batch(map, _robot(robot), [0], first, 1, period, noise, bool(state_only), action_mode,
                            **rates)
        self.map = MapInfo(probe)
        self._kinds = camera_kinds(camera)
        size = image_size(camera_size)
        self._radio = bool(radio)
        self._args = (map, _robot(robot), period, noise, bool(state_only), action_mode,
                      size if self._kinds else None, rates)
        self._space = self._base_space = with_extras(observation_space(state_only, flat), self._kinds, size,
                                                     self.n if radio else 0)
        self._probe = probe  # checks configure()'s texts before the first reset
        self._realism = {}
        self._starts = None if starts is None else np.asarray(starts, dtype=np.float64)
        if self._starts is not None and self._starts.shape != (self.n, 4):
            raise ValueError(f"starts: expected shape ({self.n}, 4), got {self._starts.shape}")
        if self._starts is not None:
            for i, p in enumerate(self._starts):
                if not np.all(np.isfinite(p)):
                    raise ValueError(f"starts[{i}]: not finite: {p.tolist()}")
                self.map.check_inside(p[:3], f"starts[{i}]")
        self._tasks = Tasks(task, self.n, self.map, start="random", n_waypoints=n_waypoints,
                            waypoint_radius=waypoint_radius, max_steps=max_steps, state_only=state_only, flat=flat)
        self._batch = None
        self._rng = np.random.default_rng()
        self._view = None
        self._closed = False
        self._replay = None

    @functools.lru_cache(maxsize=None)
    def observation_space(self, agent):
        return self._space

    @functools.lru_cache(maxsize=None)
    def action_space(self, agent):
        return action_space()

    def configure(self, *, faults: str | None = None, randomize: str | None = None,
                  rotor_speeds: bool | None = None) -> None:
        """As :meth:`UsarsimEnv.configure <usarsim.UsarsimEnv.configure>`, for every UAV of the
        world, from the next reset on: robot ``k`` of a faults file is ``uav_{k-1}``; each
        UAV draws its own randomised parameters (the reset's ``infos[agent]["randomized"]``);
        ``rotor_speeds`` adds the key to every agent's observation. ``None`` leaves a setting
        as it is; a bad text is a ValueError naming the entry, line or key."""
        (self._batch or self._probe).configure(faults, randomize, rotor_speeds)
        given = {"faults": faults, "randomize": randomize, "rotor_speeds": rotor_speeds}
        self._realism.update({k: v for k, v in given.items() if v is not None})
        if rotor_speeds is not None:
            keys = self._tasks.keys
            if rotor_speeds and "rotor_speeds" not in keys:
                keys.append("rotor_speeds")
            elif not rotor_speeds and "rotor_speeds" in keys:
                keys.remove("rotor_speeds")
            self._space = with_rotor_speeds(self._base_space, self._tasks.flat) if rotor_speeds else self._base_space
            MultiUavEnv.observation_space.cache_clear()

    def randomized(self):
        """The parameters each agent drew at the last reset (empty dicts without)."""
        return {} if self._batch is None else dict(zip(self.possible_agents, self._batch.randomized()))

    def _split(self, arrays):
        images = {}
        if self._kinds:
            images = self._batch.images(rgb="rgb" in self._kinds, depth="depth" in self._kinds)
        signals = self._batch.signals()[0] if self._radio else None
        return {a: add_extras(self._tasks.row(arrays, i), images, i, None if signals is None else signals[i])
                for i, a in enumerate(self.possible_agents) if a in self.agents}

    def reset(self, seed=None, options=None):
        if self._closed:
            raise ClosedEnvironmentError("reset: the environment is closed")
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        return self._restore(self._rng.bit_generator.state, options)

    def _restore(self, rng_state, options):
        self._rng = _rng(rng_state)
        if options and ("faults" in options or "randomize" in options):
            self.configure(faults=options.get("faults"), randomize=options.get("randomize"))
        self._replay = {"rng": rng_state, "options": options, "actions": []}
        starts = self._tasks.new_starts(self._rng, range(self.n), True, options, poses=self._starts)
        seed = _seed(self._rng)
        if self._batch is None:
            map_, robot, period, noise, state_only, action_mode, camera, rates = self._args
            self._batch = _core.Batch(map_, robot, [seed], starts, self.n, period, noise, state_only,
                                      action_mode, camera, **rates)
            if not self._realism:
                seed = None  # the new world is the reset
            else:
                self._batch.configure(**self._realism)
        if seed is not None:
            self._batch.reset([0], [seed], starts)
        self.agents = list(self.possible_agents)
        self._raw = self._batch.observe()
        self._tasks.begin(self._raw, range(self.n))
        self._trails = [[p[:2].copy()] for p in self._raw["position"]]
        drawn = self.randomized()
        infos = {a: ({"randomized": drawn[a]} if drawn.get(a) else {}) for a in self.agents}
        return self._split(self._tasks.observe(self._raw)), infos

    def step(self, actions):
        if self._closed:
            raise ClosedEnvironmentError("step: the environment is closed")
        if self._batch is None:
            raise ResetNeeded("step: call reset() first")
        if not self.agents:
            raise ResetNeeded("step: every agent's episode has ended: call reset()")
        a = np.zeros((self.n, 4))
        for agent, act in actions.items():
            if agent not in self.agents:
                raise ValueError(f"actions: {agent!r} is not a live agent (live: {self.agents})")
            a[self.possible_agents.index(agent)] = _actions(act, 1)[0]
        self._batch.step(a)
        self._replay["actions"].append({k: np.array(v, copy=True) for k, v in actions.items()})
        raw = self._raw = self._batch.observe()
        for t, p in zip(self._trails, raw["position"]):
            t.append(p[:2].copy())
        reward, term, trunc, info = self._tasks.reward(raw)
        obs = self._split(self._tasks.observe(raw))
        live = [self.possible_agents.index(a) for a in self.agents]
        out = (
            obs,
            {self.possible_agents[i]: float(reward[i]) for i in live},
            {self.possible_agents[i]: bool(term[i]) for i in live},
            {self.possible_agents[i]: bool(trunc[i]) for i in live},
            {self.possible_agents[i]: {k: v[i] for k, v in info.items()} for i in live},
        )
        self.agents = [self.possible_agents[i] for i in live if not (term[i] or trunc[i])]
        return out

    def render(self):
        if self.render_mode != "rgb_array" or self._batch is None:
            return None
        if self._view is None:
            self._view = TopView(self.map)
        raw = self._raw
        t = self._tasks
        targets = [t.targets[i, t.index[i]:t.count[i]] for i in range(self.n)]
        return self._view.draw(raw["position"], raw["attitude"][:, 2], raw.get("laser"), self._trails, targets)

    def close(self):
        self._batch = None
        self._closed = True
