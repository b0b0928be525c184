"""usarsim.MultiUavRLlibEnv against RLlib itself: its env checker and its env runner."""

import math

import pytest

import usarsim

pytest.importorskip("ray.rllib")


class _EndsApart(usarsim.MultiUavRLlibEnv):
    """Two UAVs in the empty room and one waypoint: uav_0 starts on it, uav_1 far from it."""

    def __init__(self, config=None):
        super().__init__({"n": 2, "task": "waypoints", "starts": [[2.5, -3.1, -2.6, 0.0], [-8.4, 5.4, -1.2, 0.0]],
                          "max_steps": 5, "state_only": True, "flat": True})

    def reset(self, *, seed=None, options=None):
        return super().reset(seed=seed, options={"waypoints": [[2.5, -3.1, -2.6]]})


@pytest.mark.parametrize("config", [
    {"n": 2, "task": "hover", "max_steps": 3},
    {"n": 3, "task": "waypoints", "state_only": True, "flat": True},
    {"n": 2, "task": "hover", "max_steps": 1},
], ids=["hover-dict", "waypoints-flat", "ends-on-first-step"])
def test_rllibs_env_checker_accepts_the_multi_uav_env(config):
    # RLlib's env runner runs this checker (a reset and one step) before it samples. It wants
    # every agent a step returns in `env.agents` after that step: an adapter that dropped the
    # agents ending in the step made RLlib refuse to start when an episode could end on its
    # first step ("has agent_ids that are not the names of the agents in the env").
    from ray.rllib.utils.pre_checks.env import check_multiagent_environments

    check_multiagent_environments(usarsim.MultiUavRLlibEnv(config))  # raises on a faulty env


def test_rllibs_env_runner_samples_agents_that_end_apart():
    # RLlib's own sampler (the one train_rllib_ppo.py uses): uav_0 ends on its first step
    # (it starts on its waypoint), uav_1 flies on until the episode is truncated at step 5.
    pytest.importorskip("torch")
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.env.multi_agent_env_runner import MultiAgentEnvRunner

    config = (
        PPOConfig()
        .environment(_EndsApart)
        .multi_agent(policies={"uav"}, policy_mapping_fn=lambda agent_id, episode, **kw: "uav")
    )
    runner = MultiAgentEnvRunner(config=config)
    try:
        episodes = runner.sample(num_episodes=2, random_actions=True)
    finally:
        runner.stop()
    assert len(episodes) == 2
    for episode in episodes:
        assert episode.is_done and len(episode) == 5
        first, second = episode.agent_episodes["uav_0"], episode.agent_episodes["uav_1"]
        assert (len(first), first.is_terminated) == (1, True)
        # (RLlib marks uav_1 terminated as well: its rule for an episode whose agents ended
        # some terminated and some truncated.)
        assert (len(second), second.is_truncated) == (5, True)
        assert math.isfinite(episode.get_return())


def test_env_config_carries_faults_randomisation_and_rotor_speeds():
    # RLlib builds envs from env_config alone: the realism settings must travel in it.
    env = usarsim.MultiUavRLlibEnv({"n": 2, "task": "hover", "robot": "stsQuadrotor", "state_only": True,
                                    "randomize": "mass = [0.8, 1.2]", "rotor_speeds": True})
    assert env.observation_spaces["uav_1"]["rotor_speeds"].shape == (4,)
    obs, infos = env.reset(seed=3)
    assert env.observation_spaces["uav_0"].contains(obs["uav_0"])
    assert all(0.8 <= infos[a]["randomized"]["mass"] <= 1.2 for a in env.agents)
    with pytest.raises(ValueError, match="randomize"):
        usarsim.MultiUavRLlibEnv({"n": 2, "randomize": "mass = [2, 1]"})
