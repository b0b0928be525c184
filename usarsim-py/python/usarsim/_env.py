"""The Gymnasium environment and the vector environment."""

from __future__ import annotations

import dataclasses
from typing import Any

import gymnasium as gym
import numpy as np
from gymnasium.error import ClosedEnvironmentError, ResetNeeded
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from . import _core
from ._maps import MapInfo
from ._render import TopView
from ._task import (Streams, Tasks, action_space, add_extras, camera_kinds, image_size, observation_space, with_extras,
                    with_rotor_speeds)


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
    if not np.isfinite(a).all():
        r, c = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(f"action: row {r}, component {c} is not finite ({a[r, c]})")
    return a


def _rates(physics_rate, sensor_rates, robots=None) -> dict:
    """The ``physics_rate``, ``sensor_rates`` and ``robots`` options as the core takes them (keyword
    arguments of ``_core.Batch``); a value that is not a number is a ValueError naming the
    sensor and the value (the core checks the numbers: positive, within the physics rate)."""
    out = {}
    if physics_rate is not None:
        try:
            out["physics_rate"] = float(physics_rate)
        except (TypeError, ValueError):
            raise ValueError(f"physics_rate: expected a number of Hz, got {physics_rate!r}") from None
    if sensor_rates:
        if not isinstance(sensor_rates, dict):
            raise ValueError(f"sensor_rates: expected a dict of sensor name to Hz, e.g. {{'IMU': 500}}, "
                             f"got {sensor_rates!r}")
        rates = []
        for name, hz in sensor_rates.items():
            if isinstance(hz, bool):
                hz = str(hz)
            try:
                rates.append((str(name), float(hz)))
            except (TypeError, ValueError):
                raise ValueError(f"sensor_rates: sensor {name}: the rate {hz!r} is not a number of Hz") from None
        out["sensor_rates"] = rates
    if robots is not None:
        out["robots"] = str(robots)
    return out


def _seed(rng: np.random.Generator) -> int:
    """A world seed: ``int(rng.integers(0, 2**63 - 1))``, bit for bit, from the raw draw as
    NumPy's Lemire method makes it (64-bit product, rejected when its low half is below
    2) — a fifth of the time, which a batch of resets pays once per sub-environment."""
    while True:
        m = rng.bit_generator.random_raw() * (2**63 - 1)
        if m & 0xFFFF_FFFF_FFFF_FFFF >= 2:
            return m >> 64


def _render_mode(render_mode, allowed=("rgb_array",)):
    if render_mode is not None and render_mode not in allowed:
        raise ValueError(f"render_mode: expected None or one of {list(allowed)}, got {render_mode!r}")
    return render_mode


def _rng(state) -> np.random.Generator:
    """A generator in the saved bit-generator `state`."""
    rng = np.random.Generator(getattr(np.random, state["bit_generator"])())
    rng.bit_generator.state = state
    return rng


class Replay:
    """What an env pickles: its recipe (constructor arguments), the random state at its last
    reset, that reset's options and the actions since. Unpickling builds the env from the
    recipe, resets it from that random state and replays the actions; the simulation is
    deterministic, so the copy continues bit for bit where the original is."""

    def __getstate__(self):
        return {"recipe": self._recipe, "replay": self._replay, "spec": getattr(self, "spec", None)}

    def __setstate__(self, state):
        self.__init__(**state["recipe"])
        self.spec = state["spec"]
        replay = state["replay"]
        if replay is not None:
            self._resume(replay)

    def _resume(self, replay):
        self._restore(replay["rng"], replay["options"])
        for a in replay["actions"]:
            self.step(a)


class Realism:
    """Faults, domain randomisation and rotor speeds (docs/python.md#faults-randomisation-rotor-speeds),
    for the in-process world; they apply from the next reset. ``reset(options={"faults": text,
    "randomize": text})`` does the same for one reset on."""

    def configure(self, *, faults: str | None = None, randomize: str | None = None,
                  rotor_speeds: bool | None = None) -> None:
        """``faults``: a faults file's text (``[[fault]]`` / ``[[random]]`` entries, robot 1 the
        first UAV of each world; random times drawn from the episode's seed); ``randomize``: a
        randomisation file's text (``mass = [0.9, 1.1]`` ...; ``""`` turns it off), drawn per
        episode from its seed and reported in the reset's ``info["randomized"]``;
        ``rotor_speeds``: the four rotor speeds (rad/s) as the observation key
        ``rotor_speeds``. ``None`` leaves a setting as it is; a bad text is a ValueError
        naming the entry, line or key."""
        if getattr(self, "_server", None) is not None:
            raise ValueError("configure: only for the in-process world")
        self._batch.configure(faults, randomize, rotor_speeds)
        if rotor_speeds and "rotor_speeds" not in self._tasks.keys:
            self._tasks.keys.append("rotor_speeds")
            self._set_spaces(with_rotor_speeds)
        elif rotor_speeds is False and "rotor_speeds" in self._tasks.keys:
            self._tasks.keys.remove("rotor_speeds")
            self._set_spaces(None)

    def _options(self, options):
        """Applies the realism options of a reset (``faults``, ``randomize``)."""
        if options and ("faults" in options or "randomize" in options):
            self.configure(faults=options.get("faults"), randomize=options.get("randomize"))

    def randomized(self):
        """The parameters each UAV drew at the last reset (empty dicts without)."""
        return self._batch.randomized()


class UsarsimEnv(Realism, Replay, gym.Env):
    """One stsAirRobot in a map (`usarsim/Waypoints-v0`, `usarsim/Hover-v0`).

    Keyword options: ``map`` (embedded name or map file), ``robot``, ``start`` (a PlayerStart
    tag, ``(x, y, z[, yaw])`` or ``"random"``), ``waypoints`` (``(k, 3)`` or None for
    seeded random ones), ``n_waypoints``, ``period`` (control period, s), ``noise`` (sensor
    noise std for every part), ``max_steps``, ``server`` (``"host:port"`` to fly a running
    usar-server or USARSim instead of the in-process world), ``render_mode``, ``state_only``,
    ``flat``, ``action_mode``, ``camera`` (None, ``"depth"``, ``"rgb"`` or ``"rgbd"``: image
    observations) and ``camera_size`` (docs/python.md).
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, task: str = "waypoints", *, map: str = "empty_room", robot: str = "stsAirRobot",
                 start=None, waypoints=None, n_waypoints: int = 3, waypoint_radius: float = 0.5,
                 period: float = 0.1, noise: float | None = None, max_steps: int | None = None,
                 server: str | None = None, render_mode: str | None = None, state_only: bool = False,
                 flat: bool = False, action_mode: str = "velocity", camera: str | None = None,
                 camera_size=(64, 64), physics_rate: float | None = None,
                 sensor_rates: dict | None = None, robots: str | None = None) -> None:
        self._recipe = dict(task=task, map=map, robot=robot, start=start, waypoints=waypoints,
                            n_waypoints=n_waypoints, waypoint_radius=waypoint_radius, period=period,
                            noise=noise, max_steps=max_steps, server=server, render_mode=render_mode,
                            state_only=state_only, flat=flat, action_mode=action_mode, camera=camera,
                            camera_size=camera_size, physics_rate=physics_rate, sensor_rates=sensor_rates,
                            robots=robots)
        self.render_mode = _render_mode(render_mode)
        if state_only and server is not None:
            raise ValueError("state_only: only for the in-process world (the server's robot has its sensors)")
        if action_mode != "velocity" and server is not None:
            raise ValueError("action_mode: only 'velocity' for a remote server")
        if (physics_rate is not None or sensor_rates or robots is not None) and server is not None:
            raise ValueError("physics_rate, sensor_rates, robots: only for the in-process world (start the server "
                             "with --physics-rate, --sensor-rate and --robots)")
        self._kinds = camera_kinds(camera)
        size = image_size(camera_size)
        if self._kinds and server is not None:
            raise ValueError("camera: only for the in-process world")
        self.observation_space = with_extras(observation_space(state_only, flat), self._kinds, size)
        self.action_space = action_space()
        self._robot, self._period, self._server = _robot(robot), float(period), server
        # The in-process world (also the map geometry for a remote server running the same map).
        self._batch = _core.Batch(map, self._robot, [0], _first(map), 1, period, noise, bool(state_only),
                                  action_mode, size if self._kinds else None,
                                  **_rates(physics_rate, sensor_rates, robots))
        self.map = MapInfo(self._batch)
        self._tasks = Tasks(task, 1, self.map, start=start, waypoints=waypoints, n_waypoints=n_waypoints,
                            waypoint_radius=waypoint_radius, max_steps=max_steps, state_only=state_only, flat=flat)
        self._remote = None
        self._view = None
        self._trail: list = []
        self._raw = None
        self._ended = False
        self._closed = False
        self._replay = None

    @property
    def spec(self):
        """The registration spec, with ``max_episode_steps`` the episode's step limit
        (``max_steps``): the env truncates by itself, so make() adds no TimeLimit."""
        spec = self.__dict__.get("_spec")
        if spec is not None and spec.max_episode_steps is None:
            spec = dataclasses.replace(spec, max_episode_steps=self._tasks.max_steps)
        return spec

    @spec.setter
    def spec(self, value):
        self.__dict__["_spec"] = value

    def _observe(self):
        self._raw = (self._remote or self._batch).observe()
        return self._raw

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if self._closed:
            raise ClosedEnvironmentError("reset: the environment is closed")
        super().reset(seed=seed)
        return self._restore(self.np_random.bit_generator.state, options)

    def _set_spaces(self, extend):
        base = self.__dict__.setdefault("_base_space", self.observation_space)
        self.observation_space = extend(base, self._tasks.flat) if extend else base

    def _restore(self, rng_state, options):
        """The reset after the seeding: from the generator state `rng_state`."""
        self._options(options)
        self._np_random = _rng(rng_state)
        self._replay = {"rng": rng_state, "options": options, "actions": []}
        starts = self._tasks.new_starts(self.np_random, [0], False, options)
        if self._server is None:
            self._batch.reset([0], [_seed(self.np_random)], starts)
        else:
            if self._remote is not None:
                self._remote.close()
            self._remote = _core.Remote(self._server, self._robot, list(starts[0]), self._period)
        raw = self._observe()
        self._tasks.begin(raw, [0])
        self._trail = [raw["position"][0, :2].copy()]
        self._ended = False
        info = {"lockstep": self._remote.lockstep if self._remote else True}
        if self._remote is None and self.randomized()[0]:
            info["randomized"] = self.randomized()[0]
        return self._obs(raw), info

    def _obs(self, raw):
        """The observation of the UAV, with its camera's pictures when asked."""
        obs = self._tasks.row(self._tasks.observe(raw), 0)
        if not self._kinds:
            return obs
        images = self._batch.images(rgb="rgb" in self._kinds, depth="depth" in self._kinds)
        return add_extras(obs, images, 0)

    def step(self, action):
        if self._closed:
            raise ClosedEnvironmentError("step: the environment is closed")
        if self._raw is None:
            raise ResetNeeded("step: call reset() first")
        if self._ended:
            raise ResetNeeded("step: the episode has ended (terminated or truncated): call reset()")
        a = _actions(action, 1)
        if self._remote is not None:
            self._remote.step(list(a[0]))
        else:
            self._batch.step(a)
        self._replay["actions"].append(a[0].copy())
        raw = self._observe()
        self._trail.append(raw["position"][0, :2].copy())
        reward, term, trunc, info = self._tasks.reward(raw)
        self._ended = bool(term[0] or trunc[0])
        obs = self._obs(raw)
        return obs, float(reward[0]), bool(term[0]), bool(trunc[0]), {k: v[0] for k, v in info.items()}

    def imu_readings(self) -> np.ndarray:
        """The IMU readings of the last step (in-process world), float64 ``(k, 7)``: time (s),
        acceleration x, y, z (m/s², body frame), body rates x, y, z (rad/s); ``k`` is the IMU's
        rate times ``period`` (``sensor_rates``, docs/python.md#sensor-rates)."""
        if self._server is not None:
            raise ValueError("imu_readings: only for the in-process world")
        return self._batch.imu_readings(0)

    def render(self):
        if self.render_mode != "rgb_array" or self._raw is None:
            return None
        if self._view is None:
            self._view = TopView(self.map)
        raw = self._raw
        t = self._tasks
        return self._view.draw(raw["position"], raw["attitude"][:, 2], raw.get("laser"), [self._trail],
                               [t.targets[0, t.index[0]:t.count[0]]])

    def close(self):
        if self._remote is not None:
            self._remote.close()
            self._remote = None
        self._closed = True


def _first(map_name: str) -> np.ndarray:
    """A spawn pose for the world used before the first reset: the map's first start."""
    probe = _core.Batch(map_name, "USARBot.AirRobot", [0], np.array([[0.0, 0.0, -1000.0, 0.0]]))
    starts = probe.start_poses()
    if starts:
        _, x, y, z, yaw = starts[0]
        return np.array([[x, y, z, yaw]])
    return np.array([[0.0, 0.0, -1.0, 0.0]])


def _autoreset_mode(mode) -> AutoresetMode:
    if isinstance(mode, AutoresetMode):
        if mode in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            return mode
    else:
        for m in (AutoresetMode.NEXT_STEP, AutoresetMode.SAME_STEP):
            if mode in (m.value, m.name):
                return m
    raise ValueError(f"autoreset_mode: expected AutoresetMode.NEXT_STEP or SAME_STEP, got {mode!r}")


def _with_masks(info: dict, mask: np.ndarray) -> dict:
    """Gymnasium's vector info: each key with a boolean `_key` mask of the rows that have it."""
    out = {}
    for k, v in info.items():
        out[k] = v
        out[f"_{k}"] = mask.copy()
    return out


class UsarsimVectorEnv(Realism, Replay, VectorEnv):
    """`num_envs` independent worlds with one UAV each, stepped by Rust in one call.

    Same options as :class:`UsarsimEnv` (``camera`` included; no ``server``), plus ``autoreset_mode``:
    ``AutoresetMode.NEXT_STEP`` (default, Gymnasium's): the step after an episode ends resets
    that sub-environment, ignores its action and returns its first observation with reward
    0; ``AutoresetMode.SAME_STEP``: the step that ends an episode resets it and returns the
    first observation of the next one, the last one in ``info["final_obs"]`` and its info in
    ``info["final_info"]``. Resets run in Rust, in the same parallel pass as the step.
    """

    metadata = {"render_modes": [], "autoreset_mode": AutoresetMode.NEXT_STEP}

    def __init__(self, num_envs: int, task: str = "waypoints", *, map: str = "empty_room",
                 robot: str = "stsAirRobot", start=None, waypoints=None, n_waypoints: int = 3,
                 waypoint_radius: float = 0.5, period: float = 0.1, noise: float | None = None,
                 max_steps: int | None = None, autoreset_mode=AutoresetMode.NEXT_STEP,
                 state_only: bool = False, flat: bool = False, action_mode: str = "velocity",
                 camera: str | None = None, camera_size=(64, 64), copy: bool = True,
                 physics_rate: float | None = None, sensor_rates: dict | None = None,
                 robots: str | None = None) -> None:
        if not (isinstance(num_envs, (int, np.integer)) and not isinstance(num_envs, bool) and num_envs >= 1):
            raise ValueError(f"num_envs: expected an integer >= 1, got {num_envs!r}")
        if not isinstance(copy, (bool, np.bool_)):
            raise ValueError(f"copy: expected True or False, got {copy!r}")
        self._recipe = dict(num_envs=num_envs, task=task, map=map, robot=robot, start=start,
                            waypoints=waypoints, n_waypoints=n_waypoints, waypoint_radius=waypoint_radius,
                            period=period, noise=noise, max_steps=max_steps, autoreset_mode=autoreset_mode,
                            state_only=state_only, flat=flat, action_mode=action_mode, camera=camera,
                            camera_size=camera_size, copy=copy, physics_rate=physics_rate,
                            sensor_rates=sensor_rates, robots=robots)
        self.metadata = {**type(self).metadata, "autoreset_mode": _autoreset_mode(autoreset_mode)}
        self.copy = bool(copy)
        # The env's own arrays: Rust writes the raw observation into `_raw` and the task its
        # observation into `_obs` each step, in place (made at the first step, again when
        # configure() changes the spaces).
        self._raw, self._obs = None, None
        self.num_envs = int(num_envs)
        self._kinds = camera_kinds(camera)
        size = image_size(camera_size)
        self.single_observation_space = with_extras(observation_space(state_only, flat), self._kinds, size)
        self.single_action_space = action_space()
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        first = _first(map)
        self._batch = _core.Batch(map, _robot(robot), [0] * self.num_envs, np.repeat(first, self.num_envs, 0),
                                  1, period, noise, bool(state_only), action_mode, size if self._kinds else None,
                                  **_rates(physics_rate, sensor_rates, robots))
        self.map = MapInfo(self._batch)
        self._tasks = Tasks(task, self.num_envs, self.map, start=start, waypoints=waypoints,
                            n_waypoints=n_waypoints, waypoint_radius=waypoint_radius, max_steps=max_steps,
                            state_only=state_only, flat=flat)
        self._autoreset = np.zeros(self.num_envs, dtype=bool)
        self._replay = None

    def reset(self, *, seed=None, options=None):
        if self.closed:
            raise ClosedEnvironmentError("reset: the environment is closed")
        super().reset(seed=seed)
        if seed is not None:
            streams = Streams.seeded(seed, self.num_envs)
        elif self._replay is None:
            streams = Streams.seeded(_seed(self.np_random), self.num_envs)
        else:
            streams = self._streams
        return self._restore(streams.state(), options)

    def _set_spaces(self, extend):
        self._raw, self._obs = None, None
        base = self.__dict__.setdefault("_base_space", self.single_observation_space)
        single = extend(base, self._tasks.flat) if extend else base
        self.single_observation_space = single
        self.observation_space = batch_space(single, self.num_envs)

    def _restore(self, rng_state, options):
        """The reset after the seeding: from the streams' state `rng_state` (keys, draws)."""
        self._options(options)
        self._streams = Streams(*rng_state)
        self._replay = self._record(rng_state, options)
        rows = np.arange(self.num_envs)
        self._batch.reset(rows, *self._new_worlds(rows, options))
        self._autoreset[:] = False
        raw = self._observe_raw()
        self._tasks.begin(raw, rows)
        drawn = self.randomized()
        return self._observe_all(raw), ({"randomized": drawn} if any(drawn) else {})

    def _observe_raw(self):
        """The batch's observation, written by Rust into the env's own arrays."""
        if self._raw is None:
            self._raw = self._batch.observe()
        else:
            self._batch.observe_into(self._raw)
        return self._raw

    def _step_raw(self, a, reset=None):
        """Steps the batch and returns its observation: written by Rust into the env's own
        arrays by each world, on the worker threads, in the step's own pass."""
        if self._raw is None:
            self._batch.step(a, reset)
            return self._observe_raw()
        self._batch.step(a, reset, out=self._raw)
        return self._raw

    def _observe_all(self, raw, observed=False):
        """Every sub-environment's observation, with the cameras' pictures when asked: the
        env's own arrays, filled in place (copies of them with ``copy=True``); `observed`:
        already filled by the step (:meth:`_step_task`)."""
        if self._obs is None:
            self._obs = self._tasks.observe(raw)
        elif not observed:
            self._tasks.observe(raw, out=self._obs)
        obs = self._obs
        if self.copy:
            obs = {k: v.copy() for k, v in obs.items()} if isinstance(obs, dict) else obs.copy()
        if not self._kinds:
            return obs
        out = dict(obs) if isinstance(obs, dict) else {"state": obs}
        out.update(self._batch.images(rgb="rgb" in self._kinds, depth="depth" in self._kinds))
        return out

    def _step_task(self, a, reset, live):
        """Steps the batch with the task's rewards and observations worked out in the same
        pass (``Tasks.step``), once the env's arrays exist (else the step, then the task):
        (raw, reward, terminated, truncated, info, observed)."""
        if self._raw is None or self._obs is None:
            raw = self._step_raw(a, reset)
            return (raw, *self._tasks.reward(raw, live), False)
        out = self._tasks.step(self._batch, a, reset, self._raw, live, self._obs)
        return (self._raw, *out, True)

    def _record(self, rng_state, options):
        """A fresh record of the run for pickling: the actions since the last reset; once
        every sub-env has autoreset since, only those since the oldest of their last
        autoresets (each row's step and draws made then: `reset_step` (-1: not yet),
        `reset_drawn`), so that the record stays as short as an episode however long the
        run."""
        n = self.num_envs
        return {"rng": rng_state, "options": options, "actions": [],
                "keys": self._streams.keys.copy(), "reset_step": np.full(n, -1, dtype=np.int64),
                "reset_drawn": np.zeros(n, dtype=np.uint64)}

    def _new_worlds(self, rows, options=None):
        """Seeds and starts of fresh worlds for `rows` (and their new tasks)."""
        starts = self._tasks.new_starts(self._streams, rows, False, options)
        return self._streams.seeds(rows), starts

    def step(self, actions):
        if self.closed:
            raise ClosedEnvironmentError("step: the environment is closed")
        if self._replay is None:
            raise ResetNeeded("step: call reset() first")
        a = _actions(actions, self.num_envs)
        self._replay["actions"].append(a.copy())
        if self.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP:
            return self._step_same(a)
        return self._step_next(a)

    def _step_next(self, a, forced=()):
        """A NEXT_STEP step; the rows in `forced` reset in it too (replaying a record)."""
        done = np.flatnonzero(self._autoreset)
        if len(forced):
            done = np.union1d(done, np.asarray(forced, dtype=np.int64)).astype(np.int64)
        replay = self._replay
        if len(done):
            replay["reset_step"][done] = len(replay["actions"]) - 1
            replay["reset_drawn"][done] = self._streams.drawn[done]
            oldest = replay["reset_step"].min()
            if oldest >= 0:
                # Every sub-env has reset since: forget the steps before the oldest last reset.
                if oldest > 0:
                    del replay["actions"][:oldest]
                    replay["reset_step"] -= oldest
                replay["rng"], replay["options"] = None, None
        reset = (done, *self._new_worlds(done)) if len(done) else None
        live = np.ones(self.num_envs, dtype=bool)
        live[done] = False
        # The reset rows begin their episodes in the rewards.
        raw, reward, term, trunc, info, observed = self._step_task(a, reset, live)
        self._autoreset = term | trunc
        return self._observe_all(raw, observed), reward, term, trunc, _with_masks(info, live)

    def _resume(self, replay):
        if replay["rng"] is not None:
            return super()._resume(replay)
        # A shortened record: any worlds, then each sub-env reset at its recorded step from
        # its recorded draws, and the steps replayed.
        keys, steps, drawn = replay["keys"], replay["reset_step"], replay["reset_drawn"]
        self._restore((keys, drawn), None)
        self._replay = self._record(None, None)
        for k, a in enumerate(replay["actions"]):
            forced = np.flatnonzero(steps == k)
            self._streams.drawn[forced] = drawn[forced]
            self._replay["actions"].append(np.array(a, copy=True))
            self._step_next(np.asarray(a), forced)
        self._replay = {**self._record(None, None), "actions": [np.array(a, copy=True) for a in replay["actions"]],
                        "reset_step": steps.copy(), "reset_drawn": drawn.copy()}

    def _step_same(self, a):
        live = np.ones(self.num_envs, dtype=bool)
        raw, reward, term, trunc, info, observed = self._step_task(a, None, live)
        obs = self._observe_all(raw, observed)
        infos = _with_masks(info, live)
        ended = np.flatnonzero(term | trunc)
        if len(ended):
            mask = term | trunc
            final_obs = np.full(self.num_envs, None, dtype=object)
            for i in ended:  # copies: the next observation may be written into `obs`
                final_obs[i] = {k: v[i].copy() for k, v in obs.items()} if isinstance(obs, dict) else obs[i].copy()
            infos["final_obs"], infos["_final_obs"] = final_obs, mask
            infos["final_info"] = _with_masks({k: np.where(mask, v, np.zeros_like(v)) for k, v in info.items()}, mask)
            infos["_final_info"] = mask.copy()
            self._batch.reset(ended, *self._new_worlds(ended))
            raw = self._observe_raw()
            self._tasks.begin(raw, ended)
            obs = self._observe_all(raw)
        return obs, reward, term, trunc, infos


def _register() -> None:
    for env_id, task in (("usarsim/Waypoints-v0", "waypoints"), ("usarsim/Hover-v0", "hover")):
        if env_id not in gym.registry:
            gym.register(env_id, entry_point="usarsim._env:UsarsimEnv", kwargs={"task": task},
                         vector_entry_point="usarsim._env:UsarsimVectorEnv")
