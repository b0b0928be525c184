"""Optional: PPO from stable-baselines3 on usarsim/Hover-v0 (pip install stable-baselines3).

    python train_sb3_ppo.py [timesteps]

The Dict observation needs `MultiInputPolicy`. Eight in-process environments in
stable-baselines3's DummyVecEnv; prints the mean return of the deterministic policy over ten
evaluation episodes before and after training.
"""

import sys

import gymnasium
import numpy as np
from stable_baselines3 import PPO
from stable_baselines3.common.env_util import make_vec_env
from stable_baselines3.common.evaluation import evaluate_policy

import usarsim  # noqa: F401  (registers the environments)


def main(timesteps: int) -> None:
    venv = make_vec_env("usarsim/Hover-v0", n_envs=8, seed=0, env_kwargs={"max_steps": 100})
    model = PPO("MultiInputPolicy", venv, n_steps=128, batch_size=256, learning_rate=3e-4, seed=0, verbose=0)
    eval_env = gymnasium.make("usarsim/Hover-v0", max_steps=100)
    before, _ = evaluate_policy(model, eval_env, n_eval_episodes=10, deterministic=True)
    model.learn(total_timesteps=timesteps)
    after, _ = evaluate_policy(model, eval_env, n_eval_episodes=10, deterministic=True)
    print(f"mean return over 10 episodes: {before:.2f} before, {after:.2f} after {timesteps} steps")
    np.save("ppo_hover_mean_return.npy", np.array([before, after]))


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 50_000)
