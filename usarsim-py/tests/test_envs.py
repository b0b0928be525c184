"""The Gymnasium and PettingZoo environments: API conformance, determinism, bad input."""

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

import usarsim

ENV_IDS = ["usarsim/Waypoints-v0", "usarsim/Hover-v0"]


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_check_env(env_id):
    env = gymnasium.make(env_id, render_mode="rgb_array")
    check_env(env.unwrapped, skip_render_check=False)


def test_issue_one_liner():
    env = gymnasium.make("usarsim/Waypoints-v0")
    env.reset(seed=1)
    reward = env.step(env.action_space.sample())[1]
    assert isinstance(reward, float) and np.isfinite(reward)


def test_observation_has_the_full_sensor_suite():
    env = gymnasium.make("usarsim/Waypoints-v0")
    obs, _ = env.reset(seed=0)
    assert obs["sonar"].shape == (10,) and obs["laser"].shape == (228,)
    # Empty room, 20 m square, UAV at the centre 1 m above the floor: the bottom sonar sees
    # the floor about 1 m below, the laser reads its 4 m maximum everywhere.
    assert 0.8 < obs["sonar"][9] < 1.2
    assert np.allclose(obs["laser"], 4.0)
    np.testing.assert_allclose(obs["position"], [0, 0, -1], atol=1e-6)


def rollout(env_id, seed, steps=40, **kw):
    env = gymnasium.make(env_id, **kw)
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(123)
    out = [obs]
    rewards = []
    for _ in range(steps):
        obs, r, term, trunc, _ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
        out.append(obs)
        rewards.append(r)
        if term or trunc:
            break
    return out, rewards


def same(a, b):
    return all(np.array_equal(x[k], y[k]) for x, y in zip(a, b) for k in x)


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_same_seed_same_actions_identical(env_id):
    o1, r1 = rollout(env_id, 7, noise=0.01)
    o2, r2 = rollout(env_id, 7, noise=0.01)
    assert same(o1, o2) and r1 == r2


@pytest.mark.parametrize("env_id", ENV_IDS)
def test_different_seeds_differ(env_id):
    o1, _ = rollout(env_id, 1)
    o2, _ = rollout(env_id, 2)
    assert not same(o1, o2)


def test_flying_forward_moves_forward_and_a_wall_stops_it():
    env = gymnasium.make("usarsim/Waypoints-v0", start=(0, 0, -1, 0), max_steps=1000)
    env.reset(seed=0)
    obs, *_ = env.step(np.array([1, 0, 0, 0], np.float32))
    # 2 m/s for 0.1 s.
    assert 0.15 < obs["position"][0] < 0.25
    touched = False
    for _ in range(80):
        obs, r, term, trunc, info = env.step(np.array([1, 0, 0, 0], np.float32))
        touched |= bool(info["touched"])
    assert obs["position"][0] < 10.0 and touched  # the north wall's face is at x = 10
    assert obs["laser"][114] < 0.5  # the middle beam sees the wall


def test_a_quadrotor_flown_into_a_wall_crashes_and_the_episode_ends():
    env = gymnasium.make("usarsim/Waypoints-v0", robot="stsQuadrotor", start=(7, 0, -1, 0),
                         waypoints=[[-5, 0, -1]], max_steps=1000)
    env.reset(seed=0)
    for step in range(200):
        obs, reward, term, trunc, info = env.step(np.array([1, 0, 0, 0], np.float32))
        if term:
            break
    assert term and not trunc, "the crash ends the episode"
    assert bool(info["crashed"]) and bool(info["touched"])
    assert reward < -50  # the crash penalty
    assert obs["position"][0] < 10.0  # stopped at the wall


def test_reaching_the_waypoints_ends_the_episode_with_bonuses():
    env = gymnasium.make("usarsim/Waypoints-v0", start=(0, 0, -1, 0), waypoints=[[2, 0, -1], [2, 2, -1]])
    obs, _ = env.reset(seed=0)
    total, term = 0.0, False
    for _ in range(100):
        v = obs["waypoint"]
        # Heading is 0: forward = +x, right = +y, up = -z. 2 m/s max.
        a = np.clip(np.array([v[0], v[1], -v[2], 0]) / 0.4, -1, 1).astype(np.float32)
        obs, r, term, trunc, info = env.step(a)
        total += r
        if term or trunc:
            break
    assert term and info["waypoints_reached"] == 2
    assert total > 20.0


def test_render_shows_the_walls_and_the_uav():
    env = gymnasium.make("usarsim/Waypoints-v0", render_mode="rgb_array")
    env.reset(seed=0)
    img = env.render()
    assert img.shape == (400, 400, 3) and img.dtype == np.uint8
    assert (img[0, 200] == 90).all()  # the north wall, top edge
    assert (img[200, 200] != 255).any()  # the UAV in the middle


@pytest.mark.parametrize(
    "action, words",
    [
        (np.zeros(3), "shape"),
        (np.array([0, np.nan, 0, 0]), "not finite"),
        ("fast", "action"),
    ],
)
def test_bad_actions_raise_value_error(action, words):
    env = gymnasium.make("usarsim/Waypoints-v0")
    env.reset(seed=0)
    with pytest.raises(ValueError, match=words):
        env.unwrapped.step(action)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"map": "atlantis"}, 'unknown map "atlantis"'),
        ({"robot": "Zeppelin"}, "unknown robot class"),
        ({"start": "Nowhere"}, "no PlayerStart 'Nowhere'"),
        ({"period": float("nan")}, "period"),
        ({"noise": -1.0}, "noise"),
        ({"waypoints": [[1, 2]]}, "waypoints"),
    ],
)
def test_bad_options_raise_value_error(kwargs, words):
    with pytest.raises(ValueError, match=words):
        env = gymnasium.make("usarsim/Waypoints-v0", **kwargs)
        env.reset(seed=0)


def test_start_inside_a_wall_is_a_value_error():
    env = gymnasium.make("usarsim/Waypoints-v0", start=(10.1, 0, -1, 0))
    with pytest.raises(ValueError, match="could not spawn"):
        env.reset(seed=0)


def test_vector_env_matches_single_envs_and_autoresets():
    n = 4
    venv = gymnasium.make_vec("usarsim/Hover-v0", num_envs=n, vectorization_mode="vector_entry_point", max_steps=5)
    obs, _ = venv.reset(seed=3)
    assert obs["laser"].shape == (n, 228)
    rng = np.random.default_rng(0)
    ends = 0
    for t in range(12):
        obs, r, term, trunc, _ = venv.step(rng.uniform(-1, 1, (n, 4)))
        assert r.shape == (n,)
        ends += int((term | trunc).sum())
    assert ends == 2 * n  # every sub-env truncated at 5 steps, twice, then reset
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros((n + 1, 4)))


def test_vector_env_is_deterministic():
    def run():
        venv = usarsim.vector_env(8)
        obs, _ = venv.reset(seed=11)
        rng = np.random.default_rng(1)
        for _ in range(10):
            obs, r, *_ = venv.step(rng.uniform(-1, 1, (8, 4)))
        return obs, r

    (o1, r1), (o2, r2) = run(), run()
    assert all(np.array_equal(o1[k], o2[k]) for k in o1) and np.array_equal(r1, r2)


def test_pettingzoo_parallel_api():
    from pettingzoo.test import parallel_api_test

    parallel_api_test(usarsim.multi_uav(n=3, max_steps=30), num_cycles=40)


def test_uavs_in_one_world_see_each_other():
    env = usarsim.multi_uav(n=2, starts=[[0, 0, -1, 0], [2, 0, -1, 0]])
    obs, _ = env.reset(seed=0)
    # uav_0 faces north (+x) with uav_1 2 m ahead: its middle laser beam and front sonar see it.
    assert obs["uav_0"]["laser"][114] < 2.0
    assert obs["uav_0"]["sonar"][0] < 2.0
    assert obs["uav_1"]["laser"][114] == 4.0  # uav_1 looks at the empty north of the room


def test_reset_options_choose_start_and_waypoints():
    env = gymnasium.make("usarsim/Waypoints-v0")
    obs, _ = env.reset(seed=0, options={"start": "Start2", "waypoints": [[-5, -3, -1]]})
    np.testing.assert_allclose(obs["position"], [-5, -5, -1], atol=1e-6)
    np.testing.assert_allclose(obs["waypoint"], [0, 2, 0], atol=1e-5)
    obs, _ = env.reset(seed=0, options={"start": "random"})
    assert not np.allclose(obs["position"], [-5, -5, -1])


def test_vector_and_multi_bad_input():
    venv = usarsim.vector_env(2)
    venv.reset(seed=0)
    bad = np.zeros((2, 4))
    bad[1, 3] = np.inf
    with pytest.raises(ValueError, match="row 1, component 3 is not finite"):
        venv.step(bad)
    env = usarsim.multi_uav(n=2)
    env.reset(seed=0)
    with pytest.raises(ValueError, match="'uav_7' is not a live agent"):
        env.step({"uav_7": np.zeros(4)})
    with pytest.raises(ValueError, match="shape"):
        env.step({"uav_0": np.zeros(5)})
    with pytest.raises(ValueError, match="n: expected an integer >= 1"):
        usarsim.multi_uav(n=0)


def test_remote_with_a_bad_address_is_a_value_error():
    env = gymnasium.make("usarsim/Hover-v0", server="no-such-host.invalid:3000")
    with pytest.raises(ValueError, match="no-such-host.invalid:3000"):
        env.reset(seed=0)
