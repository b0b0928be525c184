"""Image observations and the radio signal between agents (issue 20): opt-in, checked by
Gymnasium's and PettingZoo's own checkers, and showing what the world holds."""

import numpy as np
import pytest
from gymnasium import spaces
from gymnasium.utils.env_checker import check_env

import usarsim


def test_state_only_envs_have_no_images_by_default():
    env = usarsim.UsarsimEnv()
    assert "rgb" not in env.observation_space.spaces and "depth" not in env.observation_space.spaces


def test_check_env_passes_with_depth_and_rgb_images():
    env = usarsim.UsarsimEnv(camera="rgbd", camera_size=(32, 24), max_steps=20)
    check_env(env, skip_render_check=True)
    obs, _ = env.reset(seed=3)
    assert obs["rgb"].shape == (24, 32, 3) and obs["rgb"].dtype == np.uint8
    assert obs["depth"].shape == (24, 32, 1) and obs["depth"].dtype == np.float32
    assert env.observation_space.contains(obs)


def test_a_flat_observation_becomes_the_state_entry():
    env = usarsim.UsarsimEnv(camera="depth", flat=True)
    assert isinstance(env.observation_space["state"], spaces.Box)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"state", "depth"} and obs["depth"].shape == (64, 64, 1)
    check_env(env, skip_render_check=True)


def test_depth_sees_a_wall_come_closer():
    """Flying straight at the empty room's wall: the depth ahead shrinks by the distance
    flown, and matches the distance to the wall from the position (the image is of the
    world at the observation's time)."""
    env = usarsim.UsarsimEnv(camera="depth", camera_size=(16, 16), start=(0.0, 0.0, -1.0, 0.0))
    obs, _ = env.reset(seed=0)
    first = float(obs["depth"][8, 8, 0])
    for _ in range(10):
        obs, *_ = env.step(np.array([1.0, 0.0, 0.0, 0.0]))
    later = float(obs["depth"][8, 8, 0])
    flown = float(obs["position"][0])
    assert flown > 1.0
    assert later == pytest.approx(first - flown, abs=0.02)
    # The wall's inner face is at x = 10 in the empty room; the camera 0.1 m ahead of the
    # robot's centre: the picture is of the world at the observation's time.
    assert later == pytest.approx(10.0 - (flown + 0.1), abs=0.02)


def test_rgb_shows_sky_or_walls_not_black():
    env = usarsim.UsarsimEnv(camera="rgb", camera_size=(8, 8))
    obs, _ = env.reset(seed=1)
    assert obs["rgb"].max() > 50


def test_bad_camera_options_are_clear_errors():
    with pytest.raises(ValueError, match="camera: expected"):
        usarsim.UsarsimEnv(camera="thermal")
    with pytest.raises(ValueError, match="camera_size"):
        usarsim.UsarsimEnv(camera="depth", camera_size=(0, 10))
    with pytest.raises(ValueError, match="camera_size"):
        usarsim.UsarsimEnv(camera="depth", camera_size=(100000, 10))
    with pytest.raises(ValueError, match="only for the in-process world"):
        usarsim.UsarsimEnv(camera="depth", server="127.0.0.1:1")


def test_parallel_api_with_images_and_radio():
    from pettingzoo.test import parallel_api_test

    parallel_api_test(usarsim.multi_uav(n=3, max_steps=15, camera="depth", camera_size=(16, 12), radio=True),
                      num_cycles=20)


def test_the_radio_signal_fades_with_distance_and_walls():
    """Two UAVs side by side hear each other well; one behind the arena's walls less."""
    env = usarsim.multi_uav(n=2, radio=True, starts=[[0.0, 0.0, -1.0, 0.0], [1.0, 0.0, -1.0, 0.0]])
    obs, _ = env.reset(seed=0)
    near = obs["uav_0"]["signal"]
    assert near[0] == 0.0 and -93.0 < near[1] < -40.0
    assert obs["uav_1"]["signal"][0] == pytest.approx(near[1])
    far = usarsim.multi_uav(n=2, radio=True, starts=[[0.0, 0.0, -1.0, 0.0], [8.0, 0.0, -1.0, 0.0]])
    obs, _ = far.reset(seed=0)
    assert obs["uav_0"]["signal"][1] < near[1] - 5.0
    assert "signal" not in usarsim.multi_uav(n=2).observation_space("uav_0").spaces


@pytest.mark.parametrize("mode", ["next", "same"])
def test_the_vector_env_batches_images(mode):
    from gymnasium.vector import AutoresetMode

    autoreset = AutoresetMode.NEXT_STEP if mode == "next" else AutoresetMode.SAME_STEP
    env = usarsim.UsarsimVectorEnv(3, camera="rgbd", camera_size=(16, 8), max_steps=3, autoreset_mode=autoreset)
    obs, _ = env.reset(seed=0)
    assert obs["rgb"].shape == (3, 8, 16, 3) and obs["depth"].shape == (3, 8, 16, 1)
    assert env.observation_space.contains(obs)
    finals = []
    for _ in range(4):
        obs, _, term, trunc, info = env.step(np.zeros((3, 4)))
        assert env.observation_space.contains(obs)
        finals += [f for f in info.get("final_obs", []) if f is not None]
    if mode == "same":
        assert finals and finals[0]["depth"].shape == (8, 16, 1)
    single = usarsim.UsarsimEnv(camera="depth", camera_size=(16, 8), start=(0.0, 0.0, -1.0, 0.0))
    one, _ = single.reset(seed=0)
    many = usarsim.UsarsimVectorEnv(2, camera="depth", camera_size=(16, 8), start=(0.0, 0.0, -1.0, 0.0))
    both, _ = many.reset(seed=0)
    assert np.array_equal(both["depth"][0], one["depth"]), "the same picture from the same world"


@pytest.mark.parametrize("flat", [False, True])
def test_images_and_rotor_speeds_together(flat):
    """Both opt-in extensions of the observation at once (camera=... and
    configure(rotor_speeds=True)): the images and the rotor speeds are in the space and in
    every observation, dict or flat (then the speeds lengthen the state entry), and turning
    the speeds off gives the camera env's space back."""
    env = usarsim.UsarsimEnv("hover", robot="stsQuadrotor", camera="rgbd", camera_size=(16, 12),
                             flat=flat, max_steps=10)
    before = env.observation_space
    env.configure(rotor_speeds=True)
    space = env.observation_space
    assert space["rgb"].shape == (12, 16, 3) and space["depth"].shape == (12, 16, 1)
    if flat:
        assert set(space.spaces) == {"state", "rgb", "depth"}
        assert space["state"].shape == (before["state"].shape[0] + 4,)
    else:
        assert space["rotor_speeds"].shape == (4,)
    obs, _ = env.reset(seed=2)
    assert space.contains(obs)
    for _ in range(5):
        obs, *_ = env.step(np.zeros(4, dtype=np.float32))
    assert space.contains(obs)
    speeds = obs["state"][-4:] if flat else obs["rotor_speeds"]
    assert (speeds > 100).all(), "a hovering quadrotor's rotors turn"
    check_env(env, skip_render_check=True)
    env.configure(rotor_speeds=False)
    assert env.observation_space == before
    obs, _ = env.reset(seed=2)
    assert before.contains(obs)


@pytest.mark.parametrize("flat", [False, True])
def test_the_vector_env_with_images_and_rotor_speeds(flat):
    venv = usarsim.UsarsimVectorEnv(2, "hover", robot="stsQuadrotor", camera="depth", camera_size=(8, 8),
                                    flat=flat)
    venv.configure(rotor_speeds=True)
    single = venv.single_observation_space
    obs, _ = venv.reset(seed=5)
    assert venv.observation_space.contains(obs)
    assert obs["depth"].shape == (2, 8, 8, 1)
    if flat:
        assert obs["state"].shape == (2, single["state"].shape[0])
    else:
        assert obs["rotor_speeds"].shape == (2, 4)
    obs, *_ = venv.step(np.zeros((2, 4), dtype=np.float32))
    assert venv.observation_space.contains(obs)
