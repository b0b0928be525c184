"""The vector env as one batched multi-agent env: Sample Factory's shape (always tested) and
PufferLib's (with Sample Factory's own wrappers, PufferLib's vector backends when they import:
neither is a dependency, so CI skips those two)."""

import importlib.util

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import usarsim

STATE = dict(state_only=True, flat=True)


def test_sample_factory_env_is_one_multi_agent_env_with_per_agent_items():
    env = usarsim.SampleFactoryEnv(6, "hover", max_steps=3, **STATE)
    assert env.num_agents == 6 and env.is_multiagent
    assert env.observation_space.shape == (17,) and env.action_space.shape == (4,)
    obs, infos = env.reset(seed=3)
    assert obs.shape == (6, 17) and isinstance(infos, list) and len(infos) == 6
    # The same worlds as the vector env in SAME_STEP mode, step for step.
    venv = usarsim.vector_env(6, "hover", max_steps=3, autoreset_mode=AutoresetMode.SAME_STEP, **STATE)
    ref, _ = venv.reset(seed=3)
    np.testing.assert_array_equal(obs, ref)
    rng = np.random.default_rng(0)
    for n in range(7):
        a = rng.uniform(-1, 1, (6, 4))
        obs, rew, term, trunc, infos = env.step(a)
        ref, ref_rew, ref_term, ref_trunc, ref_info = venv.step(a)
        np.testing.assert_array_equal(obs, ref)
        np.testing.assert_array_equal(rew, ref_rew)
        assert (term | trunc).tolist() == (ref_term | ref_trunc).tolist()
        assert len(infos) == 6 and all(isinstance(i, dict) for i in infos)
        assert [i["touched"] for i in infos] == ref_info["touched"].tolist()
        assert not any(k.startswith("_") or k in ("final_obs", "final_info") for k in infos[0])
        if n == 2:
            # The step that ends the episodes resets them: its observation is the next
            # episode's first (not the last one's, which is in the vector env's final_obs).
            assert trunc.all()
            assert not np.array_equal(obs[0], ref_info["final_obs"][0])


def test_sample_factory_env_gives_dict_observations_one_dict_per_agent():
    env = usarsim.SampleFactoryEnv(3, "hover")
    obs, _ = env.reset(seed=1)
    assert isinstance(obs, list) and len(obs) == 3
    assert set(obs[0]) == set(env.observation_space.spaces)
    assert obs[2]["laser"].shape == (228,)
    obs, *_ = env.step(np.zeros((3, 4)))
    assert env.observation_space.contains({k: v for k, v in obs[1].items()})


def test_sample_factory_env_infos_as_arrays():
    env = usarsim.SampleFactoryEnv(5, "hover", infos="arrays", **STATE)
    env.reset(seed=0)
    info = env.step(np.ones((5, 4)))[4]
    assert isinstance(info, dict) and info["touched"].shape == (5,)


@pytest.mark.parametrize("kwargs, message", [
    (dict(autoreset_mode=AutoresetMode.NEXT_STEP), "autoreset_mode: a UAV resets in the step that ends"),
    (dict(infos="list"), "infos: expected 'agents' or 'arrays'"),
    (dict(num_agents=0), "SampleFactoryEnv: num_agents: expected an integer >= 1"),
    (dict(render_mode="human"), "render_mode: SampleFactoryEnv draws nothing"),
    (dict(max_steps=1.5), "max_steps"),
])
def test_sample_factory_env_refuses_what_it_cannot_honour(kwargs, message):
    with pytest.raises(ValueError, match=message):
        usarsim.SampleFactoryEnv(kwargs.pop("num_agents", 2), "hover", **kwargs)


def _has(module):
    # Found, not imported: importing pufferlib links a "resources" folder into the working directory.
    return importlib.util.find_spec(module) is not None


@pytest.mark.skipif(_has("pufferlib"), reason="PufferLib is installed")
def test_puffer_env_without_pufferlib_says_what_to_install():
    with pytest.raises(ImportError, match="usarsim.puffer_env needs PufferLib"):
        usarsim.puffer_env(2)


@pytest.mark.skipif(not _has("sample_factory"), reason="Sample Factory is not installed")
@pytest.mark.parametrize("batched", [False, True])
def test_sample_factorys_own_wrappers_step_it(batched):
    from pathlib import Path

    from sample_factory.algo.utils.make_env import BatchedVecEnv, NonBatchedVecEnv

    # The example's shim for Sample Factory's gymnasium < 1.0 pin (its batched wrapper reports
    # one agent under Gymnasium 1.x without it).
    path = Path(__file__).resolve().parents[1] / "examples" / "train_sample_factory.py"
    spec = importlib.util.spec_from_file_location("train_sample_factory", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    example.gymnasium_1_shim()
    env = (BatchedVecEnv if batched else NonBatchedVecEnv)(usarsim.SampleFactoryEnv(4, "hover", max_steps=2, **STATE))
    assert env.num_agents == 4 and env.is_multiagent
    obs, infos = env.reset(seed=0)
    for _ in range(3):
        obs, rew, *_, infos = env.step(np.zeros((4, 4), dtype=np.float32))
    if batched:
        assert tuple(obs["obs"].shape) == (4, 17) and tuple(rew.shape) == (4,)
    else:
        assert len(obs) == 4 and obs[0]["obs"].shape == (17,) and len(infos) == 4


@pytest.mark.skipif(not _has("pufferlib"), reason="PufferLib is not installed")
def test_pufferlibs_vector_backends_step_it(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # importing pufferlib links a "resources" folder into the working directory
    import pufferlib
    import pufferlib.vector

    native = pufferlib.vector.make(usarsim.puffer_env, env_kwargs=dict(num_agents=8, task="hover", max_steps=2,
                                                                       state_only=True))
    assert isinstance(native, pufferlib.PufferEnv) and native.num_agents == 8
    obs, infos = native.reset(seed=1)
    assert obs.shape == (8, 17) and obs is native.observations and infos == []
    native.step(np.zeros((8, 4), dtype=np.float32))
    obs, rew, term, trunc, infos = native.step(np.zeros((8, 4), dtype=np.float32))
    assert trunc.all() and rew is native.rewards and infos[0]["episodes"] == 8
    serial = pufferlib.vector.make(usarsim.puffer_env, backend=pufferlib.vector.Serial, num_envs=2,
                                   env_kwargs=dict(num_agents=4, task="hover", state_only=True))
    serial.async_reset(seed=0)
    obs = serial.recv()[0]
    assert obs.shape == (8, 17)
    serial.send(np.zeros((8, 4), dtype=np.float32))
    assert serial.recv()[0].shape == (8, 17)
    serial.close()
