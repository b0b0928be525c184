"""Type stubs of the `usarsim` package."""

from typing import Any

import gymnasium
from gymnasium import spaces

from ._core import LASER_BEAMS as LASER_BEAMS
from ._core import SONARS as SONARS
from ._core import Batch as Batch
from ._core import Command as Command
from ._core import Remote as Remote
from ._core import State as State
from ._env import UsarsimEnv as UsarsimEnv
from ._env import UsarsimVectorEnv as UsarsimVectorEnv

class Agent:
    def step(self, state: State) -> Command: ...

def fly(agent_class: type[Agent], missions: list[Any], *, server: str | None = ..., start: tuple[float, float, float] = ...,
        iterations: int = ..., log_dir: str | None = ..., map: str = ..., robot: str = ..., reached: float = ...,
        mission_timeout: float = ..., lockstep: bool = ..., quiet: bool = ...) -> dict[str, Any]: ...
def multi_uav(n: int = 2, task: str = "waypoints", **options: Any) -> Any: ...
def vector_env(num_envs: int, task: str = "waypoints", **options: Any) -> UsarsimVectorEnv: ...
def observation_space() -> spaces.Dict: ...
def action_space() -> spaces.Box: ...
