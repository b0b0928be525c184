"""RLlib PPO on the multi-UAV Hover task, one shared policy, on a local Ray with 2 CPUs.

    pip install "ray[rllib]" torch      # torch: the CPU build is enough
    python train_rllib_ppo.py [iterations]

Two UAVs in one world (usarsim.MultiUavRLlibEnv, RLlib's MultiAgentEnv), state-only flat
observations (17 floats), one policy ``uav`` shared by both agents. Prints the mean episode
return per training iteration.
"""

import sys

import ray
from ray.rllib.algorithms.ppo import PPOConfig

import usarsim


def main(iterations: int = 10) -> list:
    ray.init(num_cpus=2, include_dashboard=False, ignore_reinit_error=True)
    config = (
        PPOConfig()
        .environment(usarsim.MultiUavRLlibEnv,
                     env_config={"n": 2, "task": "hover", "max_steps": 100, "state_only": True, "flat": True})
        .env_runners(num_env_runners=1)
        .multi_agent(policies={"uav"}, policy_mapping_fn=lambda agent_id, episode, **kw: "uav")
        .training(train_batch_size_per_learner=2000, minibatch_size=250, num_epochs=6, lr=3e-4)
    )
    algo = config.build_algo()
    returns = []
    for i in range(iterations):
        result = algo.train()
        ret = result["env_runners"].get("episode_return_mean")
        returns.append(ret)
        print(f"iteration {i}: mean episode return {ret}")
    algo.stop()
    ray.shutdown()
    return returns


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
