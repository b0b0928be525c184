"""Sample Factory's APPO on Hover: 64 UAVs per env (usarsim.SampleFactoryEnv), state-only.

    pip install sample-factory        # pulls PyTorch; see docs/python.md for Gymnasium 1.x
    python train_sample_factory.py [--train_for_env_steps=2000000] [other Sample Factory flags]

One env of 64 worlds (one UAV each, 17 floats observed, velocity set-points) per rollout
worker, two workers, Sample Factory's default non-batched sampler, on the CPU. Its log prints
the mean episode return as it trains; the experiment goes to ./train_dir/usarsim_hover.
docs/python.md ("Sample Factory and PufferLib") has what it measured.
"""

import sys

from sample_factory.cfg.arguments import parse_full_cfg, parse_sf_args
from sample_factory.envs.env_utils import register_env
from sample_factory.train import run_rl

import usarsim


def gymnasium_1_shim():
    """Sample Factory 2.1 pins gymnasium < 1.0, and usarsim needs 1.x. Gymnasium 1.0 stopped
    handing attributes through wrappers, so Sample Factory's batched wrapper of a multi-agent
    env (which its main process always makes, to learn the env's spaces) reports one agent
    instead of the env's count: pass the two attributes on, as Gymnasium 0.29 did."""
    from sample_factory.algo.utils.make_env import BatchedListToDictWrapper

    for name in ("num_agents", "is_multiagent"):
        if not hasattr(BatchedListToDictWrapper, name):
            setattr(BatchedListToDictWrapper, name, property(lambda self, n=name: getattr(self.env, n)))


def make_env(full_env_name, cfg=None, env_config=None, render_mode=None):
    gymnasium_1_shim()  # in each worker process too
    return usarsim.SampleFactoryEnv(64, "hover", max_steps=100, state_only=True, flat=True)


def main(argv=None):
    gymnasium_1_shim()
    register_env("usarsim_hover", make_env)
    argv = list(sys.argv[1:] if argv is None else argv)
    if not any(a.startswith("--env") for a in argv):  # Sample Factory's first pass wants it
        argv.append("--env=usarsim_hover")
    parser, _ = parse_sf_args(argv=argv)
    parser.set_defaults(experiment="usarsim_hover", device="cpu", num_workers=2,
                        num_envs_per_worker=1, worker_num_splits=1, rollout=32, batch_size=4096,
                        num_batches_per_epoch=1, num_epochs=4, gamma=0.95, learning_rate=3e-4,
                        train_for_env_steps=2_000_000, encoder_mlp_layers=[64, 64], save_every_sec=60,
                        experiment_summaries_interval=10, decorrelate_envs_on_one_worker=False)
    cfg = parse_full_cfg(parser, argv)
    return run_rl(cfg)


if __name__ == "__main__":
    sys.exit(main())
