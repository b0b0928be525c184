"""usarsim: Gymnasium and PettingZoo environments over the usarsim-rs quadrotor simulation.

Importing the package registers ``usarsim/Waypoints-v0`` and ``usarsim/Hover-v0``::

    import gymnasium, usarsim
    env = gymnasium.make("usarsim/Waypoints-v0")
    obs, info = env.reset(seed=1)
    obs, reward, terminated, truncated, info = env.step(env.action_space.sample())

The world is the Rust simulation of usar-server, stepped in-process and in lockstep: the same
seed and actions give the same observations, bit for bit.
"""

from ._core import LASER_BEAMS, SONARS, Batch, Remote
from ._agent import Agent, fly
from ._core import Command, State
from ._env import UsarsimEnv, UsarsimVectorEnv, _register
from ._task import observation_space, action_space
from ._scenario import SCORES, ScenarioEnv, ScenarioParallelEnv, scenario_names
from ._batched import SampleFactoryEnv, puffer_env


def multi_uav(n: int = 2, task: str = "waypoints", **options):
    """A PettingZoo ParallelEnv with `n` UAVs in one world (see :class:`MultiUavEnv`)."""
    from ._multi import MultiUavEnv

    return MultiUavEnv(n, task, **options)


def vector_env(num_envs: int, task: str = "waypoints", **options) -> UsarsimVectorEnv:
    """A Gymnasium VectorEnv of `num_envs` worlds stepped by Rust in one call."""
    return UsarsimVectorEnv(num_envs, task, **options)


def __getattr__(name):
    # Optional adapters, imported on first use (their engines are not dependencies).
    if name == "MultiUavRLlibEnv":
        from ._rllib import MultiUavRLlibEnv

        return MultiUavRLlibEnv
    raise AttributeError(f"module 'usarsim' has no attribute {name!r}")


_register()

__all__ = [
    "Agent",
    "Command",
    "State",
    "fly",
    "Batch",
    "LASER_BEAMS",
    "MultiUavRLlibEnv",
    "Remote",
    "SCORES",
    "SONARS",
    "SampleFactoryEnv",
    "ScenarioEnv",
    "ScenarioParallelEnv",
    "UsarsimEnv",
    "UsarsimVectorEnv",
    "action_space",
    "multi_uav",
    "observation_space",
    "puffer_env",
    "scenario_names",
    "vector_env",
]
