"""Faults, domain randomisation and rotor speeds in the Python envs (docs/python.md)."""

import numpy as np
import pytest

import usarsim  # noqa: F401  (registers the envs)
from usarsim._env import UsarsimEnv, UsarsimVectorEnv

BIAS = """
[[fault]]
time = 0.5
robot = 1
line = "FAULT {Sensor Position} {Mode Bias} {Value 0.5}"
"""

RANDOM = """
[[random]]
probability = 0.5
robot = 1
line = "FAULT {Motor 1} {Thrust 0.3}"
"""


def quad(**kw):
    return UsarsimEnv("hover", robot="stsQuadrotor", state_only=True, **kw)


def hover(env, seed, steps=20):
    obs, info = env.reset(seed=seed)
    out = [obs]
    for _ in range(steps):
        obs, _, term, trunc, _ = env.step(np.zeros(4))
        out.append(obs)
        if term or trunc:
            break
    return out, info


def test_a_scheduled_fault_biases_the_position_from_its_time():
    healthy, _ = hover(quad(), 3)
    env = quad()
    env.unwrapped.configure(faults=BIAS)
    faulty, _ = hover(env, 3)
    # Readings before 0.5 s are the healthy ones; after it every axis reads 0.5 more.
    diffs = [f["position"] - h["position"] for f, h in zip(faulty, healthy)]
    assert np.allclose(diffs[1], 0.0, atol=1e-6)
    assert np.allclose(diffs[-1], 0.5, atol=1e-4)


def test_random_faults_repeat_under_a_seed():
    def run(seed):
        env = quad()
        env.unwrapped.configure(faults=RANDOM)
        return np.array([o["position"] for o in hover(env, seed, 60)[0]])

    a = run(5)
    assert np.array_equal(a, run(5))
    assert not np.array_equal(a, run(6))


def test_bad_texts_name_the_entry_line_and_key():
    env = quad()
    with pytest.raises(ValueError, match=r"faults: fault 1 .*1 to 4"):
        env.unwrapped.configure(faults='[[fault]]\ntime = 1\nrobot = 1\nline = "FAULT {Motor 9}"\n')
    with pytest.raises(ValueError, match=r"randomize: line 2: key `kf`"):
        env.unwrapped.configure(randomize="mass = [0.9, 1.1]\nkf = [2, 1]\n")
    with pytest.raises(ValueError, match="rotor_speeds"):
        UsarsimEnv("hover", robot="stsAirRobot").unwrapped.configure(rotor_speeds=True)


def test_each_episode_draws_its_mass_and_a_heavier_one_hovers_faster():
    env = quad()
    env.unwrapped.configure(randomize="mass = [0.7, 1.4]\nwind = [0, 0]\n", rotor_speeds=True)
    assert env.observation_space["rotor_speeds"].shape == (4,)
    first, info1 = hover(env, 1, 40)
    second, info2 = hover(env, 2, 40)
    again, info3 = hover(env, 1, 40)
    m1, m2 = info1["randomized"]["mass"], info2["randomized"]["mass"]
    assert m1 != m2, "two episodes draw different masses"
    assert info3["randomized"] == info1["randomized"], "the same seed, the same draws"
    assert all(np.array_equal(a["rotor_speeds"], b["rotor_speeds"]) for a, b in zip(first, again))
    assert env.observation_space.contains(first[-1])
    # Hover: 4 k_F ω² = m g, so ω ∝ √m.
    w1, w2 = first[-1]["rotor_speeds"].mean(), second[-1]["rotor_speeds"].mean()
    assert abs((w1 / w2) / np.sqrt(m1 / m2) - 1) < 0.02, (w1, w2, m1, m2)


def test_reset_options_and_the_vector_env():
    env = quad()
    _, info = env.reset(seed=4, options={"randomize": "mass = [0.8, 1.2]"})
    assert 0.8 <= info["randomized"]["mass"] <= 1.2
    venv = UsarsimVectorEnv(2, "hover", robot="stsQuadrotor", state_only=True)
    venv.configure(randomize="mass = [0.8, 1.2]", rotor_speeds=True)
    obs, info = venv.reset(seed=7)
    masses = [d["mass"] for d in info["randomized"]]
    assert len(masses) == 2 and masses[0] != masses[1]
    assert obs["rotor_speeds"].shape == (2, 4)
    assert venv.single_observation_space["rotor_speeds"].shape == (4,)


def test_the_draws_after_an_autoreset():
    venv = UsarsimVectorEnv(2, "hover", robot="stsQuadrotor", state_only=True, max_steps=2)
    venv.configure(randomize="mass = [0.8, 1.2]")
    _, info = venv.reset(seed=1)
    before = [d["mass"] for d in venv.randomized()]
    assert before == [d["mass"] for d in info["randomized"]]
    for _ in range(3):
        venv.step(np.zeros((2, 4)))
    after = [d["mass"] for d in venv.randomized()]
    assert after != before and all(0.8 <= m <= 1.2 for m in after)


def multi(**kw):
    pytest.importorskip("pettingzoo")
    return usarsim.multi_uav(n=2, task="hover", robot="stsQuadrotor", state_only=True, **kw)


def test_the_multi_uav_env_takes_faults_randomisation_and_rotor_speeds():
    biased = BIAS.replace("robot = 1", "robot = 2")  # robot 2 is uav_1

    def fly(env, seed, steps=12):
        obs, infos = env.reset(seed=seed)
        out = [obs]
        for _ in range(steps):
            obs, *_ = env.step({a: np.zeros(4) for a in env.agents})
            out.append(obs)
        return out, infos

    healthy, _ = fly(multi(), 3)
    env = multi()
    env.configure(faults=biased)
    faulty, _ = fly(env, 3)
    assert np.array_equal(faulty[-1]["uav_0"]["position"], healthy[-1]["uav_0"]["position"])
    assert np.allclose(faulty[-1]["uav_1"]["position"] - healthy[-1]["uav_1"]["position"], 0.5, atol=1e-4)

    env = multi()
    with pytest.raises(ValueError, match=r"randomize: line 2: key `kf`"):
        env.configure(randomize="mass = [0.9, 1.1]\nkf = [2, 1]\n")
    env.configure(randomize="mass = [0.7, 1.4]", rotor_speeds=True)
    first, infos = fly(env, 1)
    masses = [infos[a]["randomized"]["mass"] for a in env.possible_agents]
    assert masses[0] != masses[1], "each UAV draws its own mass"
    again, infos_again = fly(env, 1)
    assert infos_again == infos, "the same seed, the same draws"
    assert np.array_equal(first[-1]["uav_1"]["rotor_speeds"], again[-1]["uav_1"]["rotor_speeds"])
    assert env.observation_space("uav_0").contains(first[-1]["uav_0"])
    _, infos = env.reset(seed=2, options={"randomize": "mass = [0.8, 0.9]"})
    assert all(0.8 <= infos[a]["randomized"]["mass"] <= 0.9 for a in env.agents)
    env.configure(rotor_speeds=False, randomize="")
    obs, infos = env.reset(seed=2)
    assert "rotor_speeds" not in obs["uav_0"] and infos == {"uav_0": {}, "uav_1": {}}
