"""Issue 24, third round: batched reset draws (the same episodes, drawn for many sub-envs at
once) and the body-rates action mode."""

import gymnasium
import numpy as np
import pytest

import usarsim
from usarsim._env import _seed
from usarsim._task import Streams


# Resets draw for every sub-environment at once, and draw what one-by-one draws gave.


def test_world_seeds_are_numpys_integers_bit_for_bit():
    a, b = np.random.default_rng(11), np.random.default_rng(11)
    for _ in range(2000):
        assert _seed(a) == int(b.integers(0, 2**63 - 1))
    assert a.random() == b.random()  # the generators are left in the same state


@pytest.mark.parametrize("task, start", [("hover", None), ("hover", "random"), ("waypoints", None),
                                         ("waypoints", "random")])
def test_batched_starts_draw_what_one_by_one_starts_drew(task, start):
    venv = usarsim.vector_env(8, task, map="arena", start=start)
    tasks = venv._tasks
    rows = np.arange(8)
    batched = tasks.new_starts(Streams.seeded(3, 8), rows, False)
    targets = tasks.targets.copy()
    for i in rows:  # each row alone, from its own stream: the per-env reset
        one = tasks.new_starts(Streams.seeded(3, 8), [i], False)
        assert np.array_equal(one[0], batched[i])
    assert np.array_equal(tasks.targets, targets)
    # Another seed draws other starts and targets.
    other = tasks.new_starts(Streams.seeded(4, 8), rows, False)
    if task == "waypoints" and start is None:
        assert not np.array_equal(tasks.targets, targets)
    else:
        assert not np.array_equal(other, batched)
    if task == "hover":  # the spawns are drawn around the starts, not all on them
        assert np.any(batched[:, :3] != tasks.targets[:, 0])


# Body rates + collective thrust (QUAD {Rates}), flown by a cascaded controller.


def test_rates_mode_flies_a_quadrotor_to_a_waypoint_and_holds_it():
    env = gymnasium.make("usarsim/Waypoints-v0", robot="stsQuadrotor", action_mode="rates",
                         start=(0, 0, -2, 0), waypoints=[[2, 1, -2.5]], max_steps=200)
    assert env.action_space.shape == (4,)
    obs, _ = env.reset(seed=0)
    max_rate = 4.0  # the stsQuadrotor's max_tilt_rate, rad/s: action 1

    def rates(obs, target_xyz=None):
        (ex, ey, ez), (vx, vy, vz) = obs["waypoint"], obs["velocity"]
        # Outer loop as the attitude mode's test (heading 0): the tilt that accelerates
        # towards the waypoint; inner loop: body rates towards that tilt, yaw held at 0.
        roll = 0.6 * np.clip(0.5 * ey - 0.6 * vy, -1, 1)
        pitch = 0.6 * np.clip(-(0.5 * ex - 0.6 * vx), -1, 1)
        r, p, y = obs["attitude"]
        return np.clip([5 * (roll - r) / max_rate, 5 * (pitch - p) / max_rate, -2 * y / max_rate,
                        -0.6 * ez + 0.5 * vz], -1, 1).astype(np.float32)

    for _ in range(200):
        obs, _, term, trunc, info = env.step(rates(obs))
        if term or trunc:
            break
    assert term and info["waypoints_reached"] == 1 and not info["crashed"]
    # Hover with the same controller: it stays within 0.3 m for 5 s.
    hover = gymnasium.make("usarsim/Hover-v0", robot="stsQuadrotor", action_mode="rates",
                           start=(0, 0, -2, 0), max_steps=100)
    obs, _ = hover.reset(seed=1)
    for _ in range(30):  # from the spawn offset to the start
        obs, *_ = hover.step(rates(obs))
    for _ in range(50):
        obs, _, _, _, info = hover.step(rates(obs))
        assert np.linalg.norm(obs["waypoint"]) < 0.3 and not info["crashed"]


def test_rates_mode_turns_at_the_commanded_rate():
    env = gymnasium.make("usarsim/Hover-v0", robot="stsQuadrotor", action_mode="rates", start=(0, 0, -2, 0))
    obs, _ = env.reset(seed=0)
    for _ in range(10):  # yaw at 0.25 × 4 rad/s = 1 rad/s, level, thrust = weight
        obs, *_ = env.step(np.array([0, 0, 0.25, 0], np.float32))
    assert abs(obs["angular_velocity"][2] - 1.0) < 0.05
    assert np.all(np.abs(obs["attitude"][:2]) < 0.05)
    with pytest.raises(ValueError, match="needs a robot with physics"):
        gymnasium.make("usarsim/Hover-v0", action_mode="rates")
