"""The scenarios of ``ucc scenario`` (docs/scenarios.md) as environments.

* :class:`ScenarioEnv` — Gymnasium: the learner flies one UAV of the scenario; the others
  fly their scenario agents.
* :class:`ScenarioParallelEnv` — PettingZoo parallel: the learners fly every UAV.

The reward is the change of the scenario's **score** over the step (its metric, see
:data:`SCORES`), so an episode's return is its final score; a crash of a learner's UAV ends
the episode with -1.
"""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
from gymnasium import spaces
from gymnasium.error import ResetNeeded

from . import _core

try:
    from pettingzoo import ParallelEnv
except ImportError:  # pragma: no cover - pettingzoo is an optional extra
    ParallelEnv = object

#: What each kind of scenario is scored by (the reward is its change over a step).
SCORES = {
    "search": "coverage_pct / 100 + victims_found / victims_total (0 to 2)",
    "relay": "the fraction of the episode the endpoints have been connected (0 to 1)",
    "tracking": "the fraction of the episode a target was in view (0 to 1); with a fire "
                "only, 1 - mean update interval / time limit (0 until a point is revisited)",
    "delivery": "payloads delivered (1 each)",
}

#: The observation of one UAV (float32, 16 values): position x, y, z (m, z down), velocity
#: (3, m/s), sin and cos of the yaw, battery fraction, fraction of the time limit elapsed,
#: the score so far, then the goal relative to the UAV (x, y, z, m): the target's last
#: sighting (before the first, its start; tracking), the nearest point of the fire's perimeter, the pickup or the drop-off
#: pad (delivery), the area's centre (search) or the midpoint of the endpoints (relay); then
#: a flag (target seen recently / carrying / link up) and the number of UAVs charging.
OBS_SIZE = 16


def score(kind: str, metrics: dict, time_limit: float) -> float:
    """The score of `metrics` (:data:`SCORES`)."""
    m = {k: (0.0 if v is None else float(v)) for k, v in metrics.items()}
    t = m.get("time_s", 0.0) / time_limit if time_limit > 0 else 0.0
    if kind == "search":
        total = m.get("victims_total", 0.0)
        return m.get("coverage_pct", 0.0) / 100.0 + (m.get("victims_found", 0.0) / total if total else 0.0)
    if kind == "relay":
        return m.get("link_pct", 0.0) / 100.0 * t
    if kind == "tracking":
        if "target_seen_pct" in metrics:
            return m.get("target_seen_pct", 0.0) / 100.0 * t
        interval = metrics.get("update_interval_s")
        return 0.0 if interval is None else max(0.0, 1.0 - float(interval) / time_limit)
    return m.get("deliveries", 0.0)


class _Core:
    """What both environments share: the Rust scenario, observations and scores."""

    def _setup(self, scenario: str, controlled) -> None:
        if not isinstance(scenario, str):
            raise ValueError(f"scenario: a name ({', '.join(_core.scenarios())}) or a file, got {scenario!r}")
        self._sim = _core.Scenario(scenario, list(controlled))
        self.kind = self._sim.kind
        self.time_limit = self._sim.time_limit
        self._score = 0.0
        self._started = False
        self._briefs = []

    def _goal(self, obs: dict, i: int) -> tuple[np.ndarray, float]:
        """The goal relative to UAV `i` and the flag (:data:`OBS_SIZE`)."""
        p = np.asarray(obs["position"][i], dtype=np.float64)
        b = self._briefs[i]
        z = -b["altitude"]
        if self.kind == "tracking":
            t = obs["targets"]
            if len(t) and not math.isnan(t[0, 0]):
                return np.array([t[0, 0], t[0, 1], z]) - p, float(t[0, 3] < 1.0)
            if b.get("targets"):
                # Not seen yet: where it started.
                return np.array([b["targets"][0][0], b["targets"][0][1], z]) - p, 0.0
            if "fire_center" in b:
                c = np.array(b["fire_center"])
                r = obs["fire_radius"] if not math.isnan(obs["fire_radius"]) else b["fire_radius"]
                d = p[:2] - c
                n = float(np.hypot(*d))
                edge = c + (d / n if n > 1e-9 else np.array([1.0, 0.0])) * r
                return np.array([edge[0], edge[1], z]) - p, float(not math.isnan(obs["fire_radius"]))
            return np.zeros(3), 0.0
        if self.kind == "delivery":
            carrying = bool(obs["carrying"][i])
            pad = b["dropoff"] if carrying or self._score >= 1 else b["pickup"]
            if self._score >= 1 and not carrying:
                pad = b.get("base", b["spot"])
            return np.array(pad) - p, float(carrying)
        if self.kind == "relay":
            goal = b["slot"] if b.get("slot") is not None else b["spot"]
            return np.array(goal) - p, float(obs["link_up"])
        (x0, y0), (x1, y1) = b["area"]
        return np.array([(x0 + x1) / 2, (y0 + y1) / 2, z]) - p, 0.0

    def _observe_one(self, obs: dict, i: int) -> np.ndarray:
        goal, flag = self._goal(obs, i)
        yaw = float(obs["yaw"][i])
        row = np.concatenate([
            obs["position"][i], obs["velocity"][i],
            [math.sin(yaw), math.cos(yaw), obs["battery"][i], obs["time"] / self.time_limit, self._score],
            goal, [flag, float(np.sum(obs["charging"]))],
        ])
        return np.nan_to_num(row, nan=0.0, posinf=1e6, neginf=-1e6).astype(np.float32)

    def _advance(self, rows) -> tuple[dict, float, bool]:
        ended = self._sim.step(rows)
        obs = self._sim.observe()
        metrics = self._sim.metrics()
        new = score(self.kind, metrics, self.time_limit)
        reward, self._score = new - self._score, new
        return obs, reward, ended


def _box():
    return spaces.Box(-np.inf, np.inf, shape=(OBS_SIZE,), dtype=np.float32)


def _action_box():
    return spaces.Box(-1.0, 1.0, shape=(4,), dtype=np.float32)


class ScenarioEnv(_Core, gym.Env):
    """One UAV of a scenario flown by the learner: ``ScenarioEnv("search", uav=0)``.

    Actions: forward, right, up, yaw rate in -1..1 (fractions of the UAV's top speeds).
    Observations: :data:`OBS_SIZE` floats. Reward: the change of the score
    (:data:`SCORES`); a crash gives -1 and ends the episode. ``terminated`` when every agent
    is done (a search flown, a delivery made) or on a crash; ``truncated`` at the time limit.
    ``info`` holds the metrics so far.
    """

    metadata = {"render_modes": []}

    def __init__(self, scenario: str = "search", uav: int = 0) -> None:
        self._setup(scenario, [uav])
        self._uav = uav
        self.observation_space = _box()
        self.action_space = _action_box()

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        s = int(self.np_random.integers(0, 2**63 - 1)) if seed is None else int(seed)
        self._sim.reset(s)
        self._score, self._started = 0.0, True
        self._briefs = [self._sim.brief(i) for i in range(self._sim.uav_count)]
        obs = self._sim.observe()
        return self._observe_one(obs, self._uav), {"metrics": self._sim.metrics(), "seed": s}

    def step(self, action):
        if not self._started:
            raise ResetNeeded("step before reset")
        a = np.asarray(action, dtype=np.float64).reshape(4)
        if not np.all(np.isfinite(a)):
            raise ValueError(f"action: not finite: {a}")
        obs, reward, ended = self._advance([a.tolist()])
        crashed = bool(obs["crashed"][self._uav])
        terminated = self._sim.done() or crashed
        truncated = ended and not terminated
        if crashed:
            reward = -1.0
        if terminated or truncated:
            self._started = False
        return self._observe_one(obs, self._uav), float(reward), terminated, truncated, {"metrics": self._sim.metrics()}


class ScenarioParallelEnv(_Core, ParallelEnv):
    """Every UAV of a scenario flown by a learner (PettingZoo parallel API): agents ``uav_0``
    ... ``uav_{n-1}``; each observes its own UAV (:data:`OBS_SIZE` floats) and gets the
    team's reward (the change of the score). A crashed UAV's agent leaves ``agents``."""

    metadata = {"render_modes": [], "name": "usarsim_scenario_v0"}

    def __init__(self, scenario: str = "relay") -> None:
        if ParallelEnv is object:
            raise ImportError("ScenarioParallelEnv needs pettingzoo: pip install pettingzoo")
        probe = _core.Scenario(scenario, [])
        n = probe.uav_count
        self._setup(scenario, range(n))
        self.possible_agents = [f"uav_{i}" for i in range(n)]
        self.agents = []
        self.observation_spaces = {a: _box() for a in self.possible_agents}
        self.action_spaces = {a: _action_box() for a in self.possible_agents}
        self._rng = np.random.default_rng()

    def observation_space(self, agent):
        return self.observation_spaces[agent]

    def action_space(self, agent):
        return self.action_spaces[agent]

    def reset(self, seed=None, options=None):
        if seed is not None:
            self._rng = np.random.default_rng(seed)
        s = int(self._rng.integers(0, 2**63 - 1)) if seed is None else int(seed)
        self._sim.reset(s)
        self._score, self._started = 0.0, True
        self._briefs = [self._sim.brief(i) for i in range(self._sim.uav_count)]
        self.agents = list(self.possible_agents)
        obs = self._sim.observe()
        return ({a: self._observe_one(obs, i) for i, a in enumerate(self.possible_agents)},
                {a: {"seed": s} for a in self.agents})

    def step(self, actions):
        if not self._started:
            raise ResetNeeded("step before reset")
        rows = []
        for a in self.possible_agents:
            act = actions.get(a, np.zeros(4)) if a in self.agents else np.zeros(4)
            act = np.asarray(act, dtype=np.float64).reshape(4)
            if not np.all(np.isfinite(act)):
                raise ValueError(f"actions[{a!r}]: not finite: {act}")
            rows.append(act.tolist())
        obs, reward, ended = self._advance(rows)
        done = self._sim.done()
        live = list(self.agents)
        out_obs = {a: self._observe_one(obs, int(a.split("_")[1])) for a in live}
        rewards, terms, truncs, infos = {}, {}, {}, {}
        metrics = self._sim.metrics()
        for a in live:
            i = int(a.split("_")[1])
            crashed = bool(obs["crashed"][i])
            rewards[a] = -1.0 if crashed else float(reward)
            terms[a] = done or crashed
            truncs[a] = ended and not (done or crashed)
            infos[a] = {"metrics": metrics}
        self.agents = [a for a in live if not (terms[a] or truncs[a])]
        if not self.agents:
            self._started = False
        return out_obs, rewards, terms, truncs, infos


def scenario_names() -> list[str]:
    """The embedded scenarios (``ucc scenario --list``)."""
    return list(_core.scenarios())
