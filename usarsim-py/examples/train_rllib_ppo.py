"""RLlib PPO on the multi-UAV Hover task, one shared policy, on a local Ray with 2 CPUs.

    pip install "ray[rllib]" torch
    python train_rllib_ppo.py [iterations]

Two UAVs in one world (usarsim.MultiUavRLlibEnv, RLlib's MultiAgentEnv), state-only flat
observations (17 floats), one policy ``uav`` shared by both agents, four worlds on one env
runner. Prints, per training iteration, the mean return of that iteration's 20 episodes
(exploring policy; the two UAVs' returns added, 100 steps each) and the time so far.
Measured (Ray 2.60, PyTorch 2.15 from PyPI, CPU; 2026-11-24, 2 cores shared with other
jobs): -643.5 -> -324.6 in 30 iterations (60,000 env steps, 6 min 16 s); most of the gain
comes in the first 10-12 iterations. docs/python.md ("RLlib") has the figures.
"""

import sys
import time

import ray
from ray.rllib.algorithms.ppo import PPOConfig
from ray.rllib.core.rl_module.default_model_config import DefaultModelConfig

import usarsim


def main(iterations: int = 30) -> list:
    ray.init(num_cpus=2, include_dashboard=False, ignore_reinit_error=True)
    config = (
        PPOConfig()
        .environment(usarsim.MultiUavRLlibEnv,
                     env_config={"n": 2, "task": "hover", "max_steps": 100, "state_only": True, "flat": True})
        .env_runners(num_env_runners=1, num_envs_per_env_runner=4)
        .multi_agent(policies={"uav"}, policy_mapping_fn=lambda agent_id, episode, **kw: "uav")
        # RLlib's defaults share the value and policy layers and clip the value loss at 10:
        # with returns of -20 to -100 the value loss then swamps the policy (or is clipped
        # away) and the return hardly moves in 30 iterations.
        .rl_module(model_config=DefaultModelConfig(fcnet_hiddens=[64, 64], vf_share_layers=False))
        .training(train_batch_size_per_learner=2000, minibatch_size=256, num_epochs=10, lr=3e-4,
                  gamma=0.95, lambda_=0.95, vf_clip_param=1e6)
        .reporting(metrics_num_episodes_for_smoothing=20)  # each iteration's own 20 episodes
        .debugging(seed=0)
    )
    algo = config.build_algo()
    returns = []
    start = time.monotonic()
    for i in range(iterations):
        runners = algo.train()["env_runners"]
        ret = runners["episode_return_mean"]
        returns.append(ret)
        print(f"iteration {i}: mean episode return {ret:.1f} "
              f"({runners['num_env_steps_sampled_lifetime']:.0f} env steps, {time.monotonic() - start:.0f} s)",
              flush=True)
    algo.stop()
    ray.shutdown()
    return returns


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 30)
