"""The tasks (Waypoints, Hover) vectorized over many UAVs: observations, rewards, ends."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from ._core import LASER_BEAMS, SONARS, hover_spawns, stream_draws, task_observe, task_reward
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
    "yaw_error": 1,
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
    "yaw_error": (-np.pi, np.pi, 1),
}

#: Bounds of the opt-in rotor speeds (rad/s; docs/python.md#faults-randomisation-rotor-speeds).
BOUNDS["rotor_speeds"] = (0.0, 1e4, 4)


def with_rotor_speeds(space: spaces.Space, flat: bool) -> spaces.Space:
    """`space` with the four rotor speeds appended (a ``rotor_speeds`` key, or the flat Box
    four values longer — with images or the radio signal, the Dict's ``state`` entry)."""
    lo, hi, width = BOUNDS["rotor_speeds"]
    if flat and isinstance(space, spaces.Dict):
        return spaces.Dict({**space.spaces, "state": with_rotor_speeds(space["state"], True)})
    if flat:
        return spaces.Box(np.concatenate([space.low, np.full(width, lo, np.float32)]),
                          np.concatenate([space.high, np.full(width, hi, np.float32)]), dtype=np.float32)
    return spaces.Dict({**space.spaces, "rotor_speeds": spaces.Box(np.float32(lo), np.float32(hi), (width,), np.float32)})


#: Reward for each waypoint reached.
WAYPOINT_BONUS = 10.0
#: Reward per control period in which the body touched a wall, the floor or another UAV.
TOUCH_PENALTY = 1.0
CRASH_PENALTY = 100.0


_TWO_PI = 2 * np.pi


def _wrap(x: np.ndarray) -> np.ndarray:
    """Angles wrapped into [-pi, pi): ``(x + pi) % (2 pi) - pi`` bit for bit, in a new
    array. NumPy's ``%`` works out the quotient too; ``fmod`` with 2 pi added to the negative
    remainders gives the same numbers (a remainder of -0 stays -0, and -0 - pi is -pi as
    +0 - pi is) in less time."""
    out = np.add(x, np.pi)
    np.fmod(out, _TWO_PI, out=out)
    np.add(out, _TWO_PI, out=out, where=out < 0)
    return np.subtract(out, np.pi, out=out)


def _lengths(v: np.ndarray) -> np.ndarray:
    """The length of each row: what ``np.linalg.norm(v, axis=1)`` gives for real rows, bit
    for bit, without its checks (a third of its time with a few rows)."""
    return np.sqrt(np.add.reduce(v * v, axis=1))


def fields(state_only: bool = False) -> list:
    """The observation keys, in order (without ``sonar`` and ``laser`` when state-only)."""
    return [k for k in FIELDS if not (state_only and k in ("sonar", "laser"))]


def observation_space(state_only: bool = False, flat: bool = False) -> spaces.Space:
    """The observation space of one UAV: a Dict of float32 Boxes, or with ``flat`` one
    float32 Box of the same values concatenated in key order (docs/python.md)."""
    keys = fields(state_only)
    if flat:
        lo = np.concatenate([np.full(BOUNDS[k][2], BOUNDS[k][0]) for k in keys]).astype(np.float32)
        hi = np.concatenate([np.full(BOUNDS[k][2], BOUNDS[k][1]) for k in keys]).astype(np.float32)
        return spaces.Box(lo, hi, dtype=np.float32)
    return spaces.Dict({k: spaces.Box(np.float32(BOUNDS[k][0]), np.float32(BOUNDS[k][1]), (BOUNDS[k][2],), np.float32)
                        for k in keys})


#: The image observations of each ``camera`` option.
CAMERA_KINDS = {"depth": ("depth",), "rgb": ("rgb",), "rgbd": ("rgb", "depth")}
#: Depth observations read at most this many metres (farther, or nothing: this).
DEPTH_MAX = 100.0
#: The weakest radio signal observed, dBm (weaker reads this; the link breaks below -93).
SIGNAL_MIN = -200.0


def camera_kinds(camera) -> tuple:
    """The image keys of the ``camera`` option (None: none)."""
    if camera is None:
        return ()
    if camera not in CAMERA_KINDS:
        raise ValueError(f"camera: expected None, 'depth', 'rgb' or 'rgbd', got {camera!r}")
    return CAMERA_KINDS[camera]


def image_size(size) -> tuple:
    """``camera_size`` as (width, height), each 1..1024 pixels."""
    try:
        w, h = (int(v) for v in size)
        ok = all(float(v) == int(v) for v in size) and 1 <= w <= 1024 and 1 <= h <= 1024
    except (TypeError, ValueError):
        ok = False
    if not ok:
        raise ValueError(f"camera_size: expected (width, height), each 1 to 1024 pixels, got {size!r}")
    return w, h


def with_extras(space: spaces.Space, kinds: tuple, size: tuple, radio: int = 0) -> spaces.Space:
    """`space` with the image observations `kinds` of `size` (width, height), channel-last,
    and with `radio` > 0 the signal to each of `radio` agents: a Dict (a flat observation
    becomes its ``state`` entry). Unchanged without any."""
    if not kinds and not radio:
        return space
    items = dict(space.spaces) if isinstance(space, spaces.Dict) else {"state": space}
    w, h = size
    if "rgb" in kinds:
        items["rgb"] = spaces.Box(0, 255, (h, w, 3), np.uint8)
    if "depth" in kinds:
        items["depth"] = spaces.Box(np.float32(0.0), np.float32(DEPTH_MAX), (h, w, 1), np.float32)
    if radio:
        items["signal"] = spaces.Box(np.float32(SIGNAL_MIN), np.float32(0.0), (radio,), np.float32)
    return spaces.Dict(items)


def add_extras(obs, images: dict, i: int, signal=None):
    """Observation `obs` of UAV `i` with its rows of `images` and its `signal` row."""
    if not images and signal is None:
        return obs
    out = dict(obs) if isinstance(obs, dict) else {"state": obs}
    for k, v in images.items():
        out[k] = v[i]
    if signal is not None:
        out["signal"] = np.clip(signal, SIGNAL_MIN, 0.0).astype(np.float32)
    return out


def action_space() -> spaces.Box:
    """The action space of one UAV: four values in -1..1, read as the action mode says
    (velocity: forward, right, up, yaw rate; attitude: roll, pitch, yaw rate, thrust;
    rates: roll, pitch and yaw rates, thrust; rotors: the four rotor speeds; docs/python.md)."""
    return spaces.Box(-1.0, 1.0, (4,), np.float32)


def _pose(value, map_info: MapInfo, what: str) -> np.ndarray:
    if isinstance(value, str):
        return map_info.start(value)
    try:
        a = np.asarray(value, dtype=np.float64).ravel()
    except (TypeError, ValueError):
        a = np.zeros(0)
    if a.shape not in ((3,), (4,)) or not np.all(np.isfinite(a)):
        raise ValueError(f"{what}: expected a PlayerStart tag or finite (x, y, z[, yaw]), got {value!r}")
    map_info.check_inside(a[:3], what)
    return np.append(a, 0.0) if a.size == 3 else a


def _waypoints(value, map_info: MapInfo, what: str) -> np.ndarray:
    """Waypoints as a finite (k, 3) array, k >= 1, inside the map; ValueError naming `what`."""
    try:
        w = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        w = np.zeros((0, 0))
    if w.ndim == 1 and w.shape == (3,):
        w = w[None]
    if w.ndim != 2 or w.shape[1] != 3 or len(w) == 0 or not np.all(np.isfinite(w)):
        raise ValueError(f"{what}: expected finite waypoints of shape (k, 3), k >= 1, got shape {np.shape(value)}")
    for i, p in enumerate(w):
        map_info.check_inside(p, f"{what}[{i}]")
    return w


#: Hover's spawn offset from the start: low + span × a uniform draw in [0, 1) per axis.
_OFFSET_LOW = np.array([-1.0, -1.0, -0.5])
_OFFSET_SPAN = np.array([2.0, 2.0, 1.0])
_OFFSET_LOW_LIST, _OFFSET_SPAN_LIST = _OFFSET_LOW.tolist(), _OFFSET_SPAN.tolist()


_GOLDEN = np.uint64(0x9E3779B97F4A7C15)


def _mix(z: np.ndarray) -> np.ndarray:
    """SplitMix64's output function on a uint64 array (wrapping arithmetic)."""
    z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
    z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
    return z ^ (z >> np.uint64(31))


class Streams:
    """One random stream per sub-environment, drawn for many sub-environments at once.

    Row ``i``'s stream is SplitMix64 from a key hashed from the seed and ``i``: its ``j``-th
    64-bit draw is a function of the key and ``j`` alone. So a row draws the same whether it
    resets alone or with a thousand others, and its state is two integers (the key and the
    draws made), recorded at every autoreset for nothing (per-row NumPy generators cost a
    vector env 17 ms per 1024 resets, most of a reset step). Random starts and waypoints are
    drawn from the row's stream too, in Rust (``MapInfo.sample_rows``; a NumPy generator per
    row and the sampling loop in Python cost 0.3-0.45 s per 1024 Waypoints resets).
    """

    def __init__(self, keys, drawn) -> None:
        self.keys = np.array(keys, dtype=np.uint64)
        self.drawn = np.array(drawn, dtype=np.uint64)

    @classmethod
    def seeded(cls, seed: int, n: int) -> "Streams":
        base = _mix(np.array([int(seed) % 2**64], dtype=np.uint64))
        rows = np.arange(n, dtype=np.uint64)
        return cls(_mix(base ^ _mix(rows + _GOLDEN)), np.zeros(n, dtype=np.uint64))

    def state(self):
        """(keys, draws made): copies, for a record."""
        return self.keys.copy(), self.drawn.copy()

    def draw(self, rows, k: int) -> np.ndarray:
        """`k` 64-bit draws from each row's stream, shape (len(rows), k)."""
        # In Rust (the same numbers as `_draw_numpy`, a few times faster at 1024 rows).
        return stream_draws(self.keys, self.drawn, np.asarray(rows, dtype=np.int64), k)

    def _draw_numpy(self, rows, k: int) -> np.ndarray:
        """`draw` in NumPy: the definition `stream_draws` must equal (tests)."""
        rows = np.asarray(rows, dtype=np.int64)
        j = self.drawn[rows][:, None] + np.arange(1, k + 1, dtype=np.uint64)
        self.drawn[rows] += np.uint64(k)
        return _mix(self.keys[rows][:, None] + j * _GOLDEN)

    def doubles(self, rows, k: int) -> np.ndarray:
        """Uniform doubles in [0, 1) (the top 53 bits of a draw × 2⁻⁵³), shape (len(rows), k)."""
        return (self.draw(rows, k) >> np.uint64(11)) * (1.0 / 9007199254740992.0)

    def seeds(self, rows) -> np.ndarray:
        """A world seed (63 bits) per row, uint64."""
        return self.draw(rows, 1)[:, 0] >> np.uint64(1)


class Tasks:
    """Task state for `n` UAVs: targets, progress, step counts."""

    def __init__(self, task: str, n: int, map_info: MapInfo, *, start=None, waypoints=None,
                 n_waypoints: int = 3, waypoint_radius: float = 0.5, max_steps=None,
                 state_only: bool = False, flat: bool = False) -> None:
        self.keys, self.flat = fields(bool(state_only)), bool(flat)
        if task not in ("waypoints", "hover"):
            raise ValueError(f"task: expected 'waypoints' or 'hover', got {task!r}")
        self.task, self.n, self.map = task, n, map_info
        self.start = start
        if not (isinstance(n_waypoints, (int, np.integer)) and not isinstance(n_waypoints, bool) and n_waypoints >= 1):
            raise ValueError(f"n_waypoints: expected an integer >= 1, got {n_waypoints!r}")
        self.n_waypoints = int(n_waypoints)
        try:
            self.radius = float(waypoint_radius)
        except (TypeError, ValueError):
            self.radius = float("nan")
        if not (np.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"waypoint_radius: expected a finite number of metres > 0, got {waypoint_radius!r}")
        if max_steps is None:
            max_steps = 600 if task == "waypoints" else 200
        if not (isinstance(max_steps, (int, np.integer)) and not isinstance(max_steps, bool) and max_steps >= 1):
            raise ValueError(f"max_steps: expected an integer >= 1, got {max_steps!r}")
        self.max_steps = int(max_steps)
        self.waypoints = None if waypoints is None else _waypoints(waypoints, map_info, "waypoints")
        if self.waypoints is not None:
            self.n_waypoints = len(self.waypoints)
        if start is not None and not (isinstance(start, str) and start == "random"):
            _pose(start, map_info, "start")  # checked now, not at the first reset
        w = self.n_waypoints if task == "waypoints" else 1
        self.targets = np.zeros((n, w, 3))
        #: Waypoints of each row (a reset may give a row another count).
        self.count = np.full(n, w, dtype=np.int64)
        self.hold_yaw = np.zeros(n)
        self.index = np.zeros(n, dtype=np.int64)
        self.steps = np.zeros(n, dtype=np.int64)
        self.prev = np.zeros(n)
        self._layout_of, self._columns = None, None  # observe()'s layout, made at its first call
        self._defaults = None  # _default_starts' rows

    def default_start(self) -> np.ndarray:
        """The first PlayerStart, or (0, 0, -1)."""
        if self.map.starts:
            _, x, y, z, yaw = self.map.starts[0]
            return np.array([x, y, z, yaw])
        return np.array([0.0, 0.0, -1.0, 0.0])

    def new_starts(self, rng, rows, shared_world: bool, options=None, poses=None) -> np.ndarray:
        """Chooses starts and targets for `rows`; returns their spawn poses (len(rows), 4).
        `rng` is one generator drawn from row after row, or [`Streams`] (each row's draws from
        its own stream, as if drawn alone). `poses` (one (x, y, z, yaw) per row) overrides the
        start option."""
        options = options or {}
        start = options.get("start", self.start)
        if "start" in options and start is not None and not (isinstance(start, str) and start == "random"):
            _pose(start, self.map, "options['start']")
        waypoints = self.waypoints
        if options.get("waypoints") is not None:
            waypoints = _waypoints(options["waypoints"], self.map, "options['waypoints']")
        if waypoints is not None and self.task == "waypoints" and len(waypoints) > self.targets.shape[1]:
            pad = np.zeros((self.n, len(waypoints) - self.targets.shape[1], 3))
            self.targets = np.concatenate([self.targets, pad], axis=1)
        rows = np.asarray(rows, dtype=np.int64).reshape(-1)
        m = len(rows)
        shared = isinstance(rng, np.random.Generator)
        random_start = start is None or (isinstance(start, str) and start == "random")
        sample_start = poses is None and random_start and (start is not None or shared_world)
        if poses is not None:
            base = np.asarray(poses, dtype=np.float64)
        elif sample_start and shared:
            pts = self.map.sample(rng, m)
            base = np.column_stack([pts, rng.uniform(-np.pi, np.pi, m)])
        elif sample_start:
            # Each row's own stream, in Rust: the point, then the yaw.
            pts = self.map.sample_rows(rng, rows, 1)[:, 0]
            base = np.column_stack([pts, -np.pi + 2 * np.pi * rng.doubles(rows, 1)[:, 0]])
        elif start is None:
            base = self._default_starts(m)
        else:
            base = np.tile(_pose(start, self.map, "start"), (m, 1))
        base = base.reshape(m, 4)
        self.steps[rows] = 0
        self.index[rows] = 0
        if self.task == "hover":
            # Hold the start pose; spawn up to 1 m away from it (0.5 m vertically): each
            # row's three uniform draws, as uniform(-1, 1, 2) then uniform(-0.5, 0.5) give.
            if shared:
                self.targets[rows, 0] = base[:, :3]
                self.hold_yaw[rows] = base[:, 3]
                return self._hover_spawns_numpy(rng.random((m, 3)), base)
            # In Rust: what _hover_spawns_numpy gives with the rows' three doubles (and the
            # targets and yaws to hold written as above, in the same loop).
            return hover_spawns(rng.keys, rng.drawn, rows, base, _OFFSET_LOW_LIST, _OFFSET_SPAN_LIST,
                                self.map.boxes(0.8), -0.5, self.targets, self.hold_yaw)
        spawns = base.copy()
        if waypoints is not None:
            self.targets[rows, :len(waypoints)] = waypoints
            self.count[rows] = len(waypoints)
        elif shared:
            for k in range(m):
                self.targets[rows[k], :self.n_waypoints] = self.map.sample(rng, self.n_waypoints, spacing=1.5,
                                                                           near=base[k], radius=5.0)
            self.count[rows] = self.n_waypoints
        else:
            self.targets[rows, :self.n_waypoints] = self.map.sample_rows(rng, rows, self.n_waypoints, spacing=1.5,
                                                                         near=base, radius=5.0)
            self.count[rows] = self.n_waypoints
        return spawns

    def _default_starts(self, m: int) -> np.ndarray:
        """`default_start` in `m` rows (a read-only view of rows made once: an autoreset of
        every row asks for them at each step)."""
        if self._defaults is None or len(self._defaults) < m:
            self._defaults = np.empty((max(m, self.n), 4))
            self._defaults[:] = self.default_start()
            self._defaults.flags.writeable = False
        return self._defaults[:m]

    def _hover_spawns_numpy(self, u, base) -> np.ndarray:
        """Hover's spawns: each start `base` moved by low + span × `u` (three uniform doubles
        per row) where that place is free (0.8 m from the obstacles' boxes) and above
        z = -0.5 m; else the start. The definition `hover_spawns` must equal (tests)."""
        spawns = base.copy()
        cand = _OFFSET_SPAN * u  # in place: base + (low + span × u), the same sums
        cand += _OFFSET_LOW
        cand += base[:, :3]
        ok = self.map.free(cand, 0.8) & (cand[:, 2] < -0.5)
        np.copyto(spawns[:, :3], cand, where=ok[:, None])
        return spawns

    def _vector(self, raw) -> np.ndarray:
        tgt = self.targets[np.arange(self.n), np.minimum(self.index, self.count - 1)]
        return tgt - raw["position"]

    def begin(self, raw, rows) -> None:
        """Remembers the starting distances of `rows` after a reset."""
        rows = np.asarray(rows, dtype=np.int64)
        self.prev[rows] = _lengths(self._vector(raw))[rows]

    def observe(self, raw, out=None):
        """The observation (float32 arrays, one row per UAV): a dict, or with ``flat`` one
        array. With ``out`` (an earlier result), written into its arrays and returned.
        Worked out in Rust (`task_observe`): what :meth:`_observe_numpy` gives, bit for bit."""
        widths = {"waypoint": 3, "yaw_error": 1}
        lo, hi, columns, _ = self._layout({k: widths.get(k) or raw[k].shape[1] for k in self.keys}, len(raw["position"]))
        if out is None:
            n = len(raw["position"])
            out = (np.empty((n, len(lo)), np.float32) if self.flat
                   else {k: np.empty((n, b - a), np.float32) for k, a, b in columns})
        task_observe(self.task == "hover", self.keys, raw, self.targets, self.count, self.index, self.hold_yaw,
                     lo, hi, out)
        return out

    def _observe_numpy(self, raw, out=None):
        """:meth:`observe` in NumPy: the definition `task_observe` must equal (tests)."""
        values = {k: raw[k] for k in self.keys if k not in ("waypoint", "yaw_error")}
        values["attitude"] = _wrap(raw["attitude"])
        values["waypoint"] = self._vector(raw)
        # Hover: the yaw to hold minus the yaw (wrapped); Waypoints: 0.
        yaw_error = _wrap(self.hold_yaw - raw["attitude"][:, 2])
        values["yaw_error"] = (yaw_error if self.task == "hover" else np.zeros(self.n))[:, None]
        # Gathered into one float64 row per UAV and clipped in one call: in float64, then
        # rounded to float32, the values astype() gives.
        lo, hi, columns, scratch = self._layout({k: values[k].shape[1] for k in self.keys}, len(values["position"]))
        for k, a, b in columns:
            scratch[:, a:b] = values[k]
        if out is None:
            out = (np.empty(scratch.shape, np.float32) if self.flat
                   else {k: np.empty((len(scratch), b - a), np.float32) for k, a, b in columns})
        if self.flat:
            np.clip(scratch, lo, hi, out=out, casting="same_kind")
        else:
            np.clip(scratch, lo, hi, out=scratch)
            for k, a, b in columns:
                out[k][...] = scratch[:, a:b]
        return out

    def _layout(self, widths: dict, rows: int):
        """Per-column bounds, each key's columns and a float64 scratch array for
        :meth:`_observe_numpy`, made again when the keys, their widths (`widths`: key ->
        columns) or the number of rows change."""
        shape = (tuple(self.keys), tuple(widths[k] for k in self.keys), rows)
        if self._layout_of != shape:
            keys, widths, rows = shape
            ends = np.cumsum(widths).tolist()
            columns = [(k, e - w, e) for k, w, e in zip(keys, widths, ends)]
            lo = np.concatenate([np.full(w, BOUNDS[k][0], dtype=np.float64) for k, w in zip(keys, widths)])
            hi = np.concatenate([np.full(w, BOUNDS[k][1], dtype=np.float64) for k, w in zip(keys, widths)])
            self._layout_of, self._columns = shape, (lo, hi, columns, np.empty((rows, ends[-1])))
        return self._columns

    def row(self, obs, i: int):
        """Row `i` of an observation from :meth:`observe`."""
        return obs[i] if self.flat else {k: v[i] for k, v in obs.items()}

    def reward(self, raw, live=None):
        """Rewards, terminated and truncated flags and info arrays after one step. Rows not in
        the boolean mask `live` (sub-environments reset in this step) get reward 0, no end and
        no progress, and begin their episodes here (the distance :meth:`begin` remembers).
        Worked out in Rust (`task_reward`): what :meth:`_reward_numpy` gives, bit for bit."""
        live = np.ones(self.n, dtype=bool) if live is None else np.ascontiguousarray(live, dtype=bool)
        reward, terminated, truncated, touched, crashed, reached = task_reward(
            self.task == "hover", raw["position"], raw["attitude"], raw["touched"], raw["crashed"], raw["battery"],
            self.targets, self.count, self.index, self.steps, self.prev, self.hold_yaw, self.radius,
            self.max_steps, live)
        return reward, terminated, truncated, {"touched": touched, "crashed": crashed, "reached": reached,
                                               "waypoints_reached": self.index.copy()}

    def step(self, batch, actions, reset, raw, live, out):
        """Steps `batch` (actions and resets as ``Batch.step`` takes them) with its raw
        observation written into `raw`, and returns :meth:`reward`'s results for `live`, the
        observation :meth:`observe` gives written into `out` (an earlier result) — worked out
        by the stepping threads, each world's rows as soon as they are written
        (``Batch.step_task``): the same values, bit for bit."""
        widths = {"waypoint": 3, "yaw_error": 1}
        lo, hi, _, _ = self._layout({k: widths.get(k) or raw[k].shape[1] for k in self.keys}, self.n)
        live = np.ascontiguousarray(live, dtype=bool)
        reward, terminated, truncated, touched, crashed, reached = batch.step_task(
            actions, reset, raw, out, self.task == "hover", self.keys, self.targets, self.count, self.index,
            self.steps, self.prev, self.hold_yaw, self.radius, self.max_steps, live, lo, hi)
        return reward, terminated, truncated, {"touched": touched, "crashed": crashed, "reached": reached,
                                               "waypoints_reached": self.index.copy()}

    def _reward_numpy(self, raw, live=None):
        """Rewards, terminated and truncated flags and info arrays after one step. Rows not in
        the boolean mask `live` (sub-environments reset in this step) get reward 0, no end and
        no progress, and begin their episodes here (the distance :meth:`begin` remembers).
        :meth:`reward` in NumPy: the definition `task_reward` must equal (tests)."""
        live = np.ones(self.n, dtype=bool) if live is None else np.asarray(live, dtype=bool)
        self.steps += live
        touched = np.asarray(raw["touched"], dtype=bool)
        crashed = np.asarray(raw["crashed"], dtype=bool)
        dist = _lengths(self._vector(raw))
        if self.task == "hover":
            yaw_err = np.abs(_wrap(raw["attitude"][:, 2] - self.hold_yaw))
            reward = -dist - 0.2 * yaw_err - TOUCH_PENALTY * touched
            terminated = np.zeros(self.n, dtype=bool)
            reached = np.zeros(self.n, dtype=bool)
        else:
            reward = self.prev - dist - TOUCH_PENALTY * touched
            reached = (dist < self.radius) & live
            reward = reward + WAYPOINT_BONUS * reached
            self.index = self.index + reached
            terminated = self.index >= self.count
            dist = _lengths(self._vector(raw))
        # Live rows: the distance after this step; rows reset in it: their starting distance.
        self.prev = dist
        # A crash (robots with physics: docs/quadrotor.md) ends the episode with a penalty.
        reward = reward - CRASH_PENALTY * crashed
        terminated = (terminated | crashed) & live
        truncated = live & ~terminated & ((self.steps >= self.max_steps) | (raw["battery"][:, 0] <= 0.0))
        reward = np.where(live, reward, 0.0)
        return reward, terminated, truncated, {"touched": touched & live, "crashed": crashed & live,
                                               "reached": reached, "waypoints_reached": self.index.copy()}
