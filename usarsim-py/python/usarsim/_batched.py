"""The vector env as one env of many agents, the shape that batched trainers document: Sample
Factory's multi-agent env and PufferLib's native env. Neither engine is a dependency:
:class:`SampleFactoryEnv` needs only Gymnasium, :func:`puffer_env` imports ``pufferlib`` when
called.

Both reset a UAV in the step that ends its episode and return the next episode's first
observation there (the vector env's ``AutoresetMode.SAME_STEP``), as both engines require.
"""

from __future__ import annotations

import functools

import gymnasium as gym
import numpy as np
from gymnasium.vector import AutoresetMode

from ._env import UsarsimVectorEnv

# The vector env's info keys that are not a UAV's own (Gymnasium's masks start with "_").
_NOT_PER_AGENT = ("final_obs", "final_info")


def _vector_env(name: str, num_agents, task: str, options: dict) -> UsarsimVectorEnv:
    """The adapters' vector env: one world per agent, each reset in the step that ends it."""
    if not (isinstance(num_agents, (int, np.integer)) and not isinstance(num_agents, bool) and num_agents >= 1):
        raise ValueError(f"{name}: num_agents: expected an integer >= 1, got {num_agents!r}")
    if "autoreset_mode" in options:
        raise ValueError(f"{name}: autoreset_mode: a UAV resets in the step that ends its episode "
                         "(AutoresetMode.SAME_STEP, the engine's rule); leave it out")
    return UsarsimVectorEnv(num_agents, task, autoreset_mode=AutoresetMode.SAME_STEP, **options)


def _per_agent_infos(info: dict, n: int) -> list:
    """The vector env's info (arrays over the UAVs) as one dict per UAV."""
    keys = [k for k in info if not k.startswith("_") and k not in _NOT_PER_AGENT]
    if not keys:
        return [{} for _ in range(n)]
    # One .tolist() per key, then plain Python: no NumPy scalar made per UAV and key.
    columns = [info[k].tolist() if isinstance(info[k], np.ndarray) else [info[k]] * n for k in keys]
    return [dict(zip(keys, row)) for row in zip(*columns)]


class SampleFactoryEnv(gym.Env):
    """`num_agents` worlds of one UAV each as one Sample Factory multi-agent env.

    Sample Factory's documented interface ("Custom multi-agent environments"): ``num_agents``
    and ``is_multiagent = True``; ``observation_space`` and ``action_space`` are one agent's;
    ``reset`` returns one observation and one info dict per agent, ``step`` takes one action
    per agent and returns one observation, reward, ``terminated``, ``truncated`` and info per
    agent, and resets each agent in the step that ends its episode, returning the next
    episode's first observation. Observations are one array with a row per agent with a
    ``Box`` space (``flat=True``), else a list of one dict per agent; rewards and the flags
    are arrays. Infos are one dict per agent (``touched``, ``crashed``, ``reached``,
    ``waypoints_reached``); ``infos="arrays"`` returns the vector env's dict of arrays instead,
    which Sample Factory's batched sampler (``--batched_sampling=True``) takes as well and
    which costs nothing to build (one dict per agent is about 1 µs an agent a step). Options
    are :func:`usarsim.vector_env`'s (``autoreset_mode`` excepted). ``render_mode`` must be
    None (the worlds are not drawn).

    A Sample Factory factory function::

        def make_usarsim(full_env_name, cfg=None, env_config=None, render_mode=None):
            return usarsim.SampleFactoryEnv(64, "hover", state_only=True, flat=True)
    """

    is_multiagent = True
    metadata = {"render_modes": []}

    def __init__(self, num_agents: int, task: str = "waypoints", *, render_mode=None, infos: str = "agents",
                 **options) -> None:
        if render_mode is not None:
            raise ValueError(f"render_mode: SampleFactoryEnv draws nothing; expected None, got {render_mode!r}")
        if infos not in ("agents", "arrays"):
            raise ValueError(f"infos: expected 'agents' or 'arrays', got {infos!r}")
        self._arrays = infos == "arrays"
        self.venv = _vector_env("SampleFactoryEnv", num_agents, task, options)
        self.num_agents = self.venv.num_envs
        self.observation_space = self.venv.single_observation_space
        self.action_space = self.venv.single_action_space
        self.render_mode = None

    def _per_agent(self, obs):
        if isinstance(obs, dict):
            return [{k: v[i] for k, v in obs.items()} for i in range(self.num_agents)]
        return obs

    def reset(self, *, seed=None, options=None):
        obs, info = self.venv.reset(seed=seed, options=options)
        return self._per_agent(obs), info if self._arrays else [dict(info) for _ in range(self.num_agents)]

    def step(self, actions):
        obs, reward, terminated, truncated, info = self.venv.step(np.asarray(actions))
        if not self._arrays:
            info = _per_agent_infos(info, self.num_agents)
        return self._per_agent(obs), reward, terminated, truncated, info

    def close(self):
        self.venv.close()


def puffer_env(num_agents: int, task: str = "waypoints", *, buf=None, seed=None, **options):
    """`num_agents` worlds of one UAV each as one PufferLib native env (a ``pufferlib.PufferEnv``,
    which handles its agents' vectorization and resets itself): pass ``usarsim.puffer_env`` to
    ``pufferlib.vector.make`` (``env_kwargs={"num_agents": 256, ...}``; its ``Serial`` and
    ``Multiprocessing`` backends give each copy a ``buf`` and a ``seed``). Observations are
    the flat state (``flat=True``, PufferLib's native envs take a ``Box``); rewards, ends and
    observations are written into PufferLib's arrays (``observations``, ``rewards``,
    ``terminals``, ``truncations``) in place; ``infos`` is a list with one dict of the mean
    return and length of the episodes that ended in the step, when any did. Options are
    :func:`usarsim.vector_env`'s (``autoreset_mode`` excepted); ``seed`` seeds the first
    ``reset`` without one. Needs PufferLib (see docs/python.md for installing it beside
    Gymnasium 1.x).
    """
    return _puffer_class()(num_agents, task, buf=buf, seed=seed, **options)


@functools.cache
def _puffer_class():
    try:
        import pufferlib
    except ImportError as e:
        raise ImportError("usarsim.puffer_env needs PufferLib (pip install pufferlib; docs/python.md says how "
                          "beside Gymnasium 1.x)") from e

    class UsarsimPufferEnv(pufferlib.PufferEnv):
        __doc__ = puffer_env.__doc__

        def __init__(self, num_agents, task="waypoints", *, buf=None, seed=None, **options):
            # copy=False: each step's observation is copied into PufferLib's array at once.
            options = {"flat": True, "copy": False, **options}
            if not options["flat"] or options.get("camera"):
                raise ValueError("puffer_env: PufferLib's native envs take one Box observation: "
                                 "flat=True and no camera")
            self.venv = _vector_env("puffer_env", num_agents, task, options)
            self.single_observation_space = self.venv.single_observation_space
            self.single_action_space = self.venv.single_action_space
            self.num_agents = self.venv.num_envs
            self._seed = seed
            self._returns = np.zeros(self.num_agents)
            self._lengths = np.zeros(self.num_agents, dtype=np.int64)
            super().__init__(buf)

        def reset(self, seed=None):
            if seed is None:
                seed, self._seed = self._seed, None
            obs, _ = self.venv.reset(seed=seed)
            self.observations[:] = obs
            self._returns[:] = 0.0
            self._lengths[:] = 0
            return self.observations, []

        def step(self, actions):
            obs, reward, terminated, truncated, _ = self.venv.step(np.asarray(actions))
            self.observations[:] = obs
            self.rewards[:] = reward
            self.terminals[:] = terminated
            self.truncations[:] = truncated
            self._returns += reward
            self._lengths += 1
            ended = terminated | truncated
            infos = []
            if ended.any():
                infos.append({"episode_return": float(self._returns[ended].mean()),
                              "episode_length": float(self._lengths[ended].mean()),
                              "episodes": int(ended.sum())})
                self._returns[ended] = 0.0
                self._lengths[ended] = 0
            return self.observations, self.rewards, self.terminals, self.truncations, infos

        def close(self):
            self.venv.close()

    return UsarsimPufferEnv
