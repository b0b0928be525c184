"""RLlib's MultiAgentEnv over the multi-UAV world (optional: needs ``ray[rllib]``)."""

from __future__ import annotations

try:
    from ray.rllib.env.multi_agent_env import MultiAgentEnv
except ImportError:  # pragma: no cover - ray[rllib] is optional
    MultiAgentEnv = object

from ._multi import MultiUavEnv


class MultiUavRLlibEnv(MultiAgentEnv):
    """:class:`usarsim.multi_uav`'s world as an RLlib ``MultiAgentEnv``.

    ``config`` (RLlib's ``env_config``) holds :func:`usarsim.multi_uav`'s options (``n``,
    ``task``, ``map``, ...). Agents ``uav_0`` ... act until their own episode ends (then
    they hover, as in PettingZoo); ``terminateds["__all__"]`` / ``truncateds["__all__"]``
    end the episode once every agent has ended (``terminateds`` when all of them terminated,
    ``truncateds`` otherwise). Agents without an action in ``step`` hover. ``agents`` lists
    the agents the last ``reset`` or ``step`` returned (RLlib's env checker wants every
    returned agent in it); an agent that has ended leaves it at the next ``step``.
    ``faults``, ``randomize`` and ``rotor_speeds`` in ``config`` go to
    :meth:`MultiUavEnv.configure <usarsim._multi.MultiUavEnv.configure>` (RLlib makes its
    envs from ``env_config`` alone).
    """

    def __init__(self, config: dict | None = None) -> None:
        if MultiAgentEnv is object:
            raise ImportError("usarsim.MultiUavRLlibEnv needs RLlib: pip install 'ray[rllib]'")
        super().__init__()
        options = dict(config or {})
        realism = {k: options.pop(k) for k in ("faults", "randomize", "rotor_speeds") if k in options}
        self.env = MultiUavEnv(**options)
        self.env.configure(**realism)
        self.possible_agents = list(self.env.possible_agents)
        self.agents = list(self.possible_agents)
        self.observation_spaces = {a: self.env.observation_space(a) for a in self.possible_agents}
        self.action_spaces = {a: self.env.action_space(a) for a in self.possible_agents}
        self._terminated: dict = {}

    def reset(self, *, seed=None, options=None):
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        self._terminated = {}
        return obs, infos

    def step(self, action_dict):
        actions = {a: v for a, v in action_dict.items() if a in self.env.agents}
        obs, rewards, terms, truncs, infos = self.env.step(actions)
        for a in terms:
            if terms[a] or truncs[a]:
                self._terminated[a] = bool(terms[a])
        self.agents = list(rewards)
        over = not self.env.agents
        all_terminated = over and all(self._terminated.values())
        return (obs, rewards, {**terms, "__all__": all_terminated}, {**truncs, "__all__": over and not all_terminated},
                infos)

    def render(self):
        return self.env.render()

    def close(self):
        self.env.close()
