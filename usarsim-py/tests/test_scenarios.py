"""The scenarios of `ucc scenario` as Gymnasium and PettingZoo environments."""

import math

import numpy as np
import pytest
from gymnasium.error import ResetNeeded
from gymnasium.utils.env_checker import check_env

import usarsim
from usarsim import ScenarioEnv, ScenarioParallelEnv, scenario_names
from usarsim._scenario import OBS_SIZE, score


def test_every_embedded_scenario_is_listed():
    names = scenario_names()
    for n in ["search", "search-team", "relay", "tracking", "perimeter", "delivery"]:
        assert n in names


def test_the_single_uav_env_passes_gymnasiums_checks():
    env = ScenarioEnv("tracking")
    check_env(env, skip_render_check=True)
    obs, info = env.reset(seed=3)
    assert obs.shape == (OBS_SIZE,) and obs.dtype == np.float32
    assert info["seed"] == 3


def test_the_parallel_env_passes_pettingzoos_api_test():
    from pettingzoo.test import parallel_api_test

    env = ScenarioParallelEnv("perimeter")
    assert env.possible_agents == ["uav_0", "uav_1", "uav_2"]
    parallel_api_test(env, num_cycles=30)


def test_the_return_is_the_final_score_and_the_other_uavs_fly_their_agents():
    # The learner flies a spare of the relay (it stays on the pad); the chain is the agents'.
    env = ScenarioEnv("relay", uav=4)
    env.reset(seed=1)
    total, steps, truncated, info = 0.0, 0, False, {}
    while not truncated:
        _, r, terminated, truncated, info = env.step(np.zeros(4))
        assert not terminated
        total += r
        steps += 1
    m = info["metrics"]
    assert steps == 6000  # 600 s at 0.1 s
    # With one spare fewer the chain still forms and rotates part of the time.
    assert m["link_pct"] > 20, m
    assert any("taking over" in line for line in env.unwrapped._sim.log())
    assert math.isclose(total, score("relay", m, 600.0), abs_tol=1e-9)
    assert math.isclose(total, m["link_pct"] / 100, abs_tol=1e-6)


def test_a_learner_that_follows_the_goal_observation_keeps_the_target_in_view():
    env = ScenarioEnv("tracking")
    obs, _ = env.reset(seed=1)
    done = False
    while not done:
        # The goal is the target's last sighting relative to the UAV (world frame); the
        # heading stays 0 (north), so world x is forward and y right.
        rel = obs[11:14]
        action = np.clip([rel[0], rel[1], rel[2] * -1.0, 0.0], -1, 1)
        obs, _, terminated, truncated, info = env.step(action)
        done = terminated or truncated
    assert info["metrics"]["target_seen_pct"] > 80, info["metrics"]


def test_the_same_seed_gives_the_same_episode():
    def run(seed):
        env = ScenarioEnv("search")
        obs, _ = env.reset(seed=seed)
        rng = np.random.default_rng(0)
        out = [obs]
        for _ in range(50):
            obs, *_ = env.step(rng.uniform(-1, 1, 4))
            out.append(obs)
        return np.array(out)

    assert np.array_equal(run(5), run(5))
    # Another seed draws the victims elsewhere: the baseline finds them elsewhere.
    def finds(seed):
        sim = usarsim._core.Scenario("search", [])
        sim.reset(seed)
        while not sim.step([]):
            pass
        return [line for line in sim.log() if "found victim Drawn" in line]

    assert finds(5) == finds(5)
    assert finds(5) != finds(6)


def test_a_crash_ends_the_episode_with_minus_one():
    env = ScenarioEnv("delivery")  # the stsQuadrotor reports crashes
    env.reset(seed=1)
    terminated = False
    for _ in range(400):
        # Full speed north, into the tower's side of the plaza... then into the ground.
        _, r, terminated, truncated, _ = env.step(np.array([1.0, 0.0, -1.0, 0.0]))
        if terminated:
            break
    assert terminated and r == -1.0


def test_bad_arguments_say_what_is_wrong():
    with pytest.raises(ValueError, match="no scenario \"atlantis\""):
        ScenarioEnv("atlantis")
    with pytest.raises(ValueError, match="out of range"):
        ScenarioEnv("search", uav=3)
    env = ScenarioEnv("search")
    with pytest.raises(ResetNeeded):
        env.step(np.zeros(4))
    env.reset(seed=1)
    with pytest.raises(ValueError, match="not finite"):
        env.step(np.array([np.nan, 0, 0, 0]))
    sim = usarsim._core.Scenario("search", [0])
    with pytest.raises(ValueError, match="before reset"):
        sim.observe()


def test_the_cem_example_learns_to_track_better_than_the_baseline_agent():
    import importlib.util
    import pathlib

    path = pathlib.Path(__file__).parent.parent / "examples" / "scenario_cem.py"
    spec = importlib.util.spec_from_file_location("scenario_cem", path)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    base = example.baseline()
    gains = example.cem(iterations=2, population=6)
    assert example.episode(gains) < base
