"""Issue 24, fourth round: observations written in place (the vector env's own arrays, filled
by Rust and by the task each step), ``copy=False``, and contact from the robot itself."""

import re

import numpy as np
import pytest
from gymnasium.vector import AutoresetMode

import usarsim


def _copy(obs):
    return {k: v.copy() for k, v in obs.items()} if isinstance(obs, dict) else obs.copy()


@pytest.mark.parametrize("options", [{}, {"flat": True}, {"state_only": True, "flat": True},
                                     {"task": "hover", "state_only": True}])
def test_observations_written_in_place_equal_fresh_ones_bit_for_bit(options):
    venv = usarsim.vector_env(12, max_steps=6, **options)
    venv.reset(seed=5)
    rng = np.random.default_rng(2)
    buffer = None
    for _ in range(15):
        venv.step(rng.uniform(-1, 1, (12, 4)))
        raw = venv._batch.observe()  # fresh arrays from Rust
        into = {k: np.full_like(v, 7) for k, v in raw.items()}
        venv._batch.observe_into(into)
        for k in raw:
            assert np.array_equal(raw[k], into[k]) and raw[k].dtype == into[k].dtype, k
        fresh = venv._tasks.observe(raw)
        buffer = venv._tasks.observe(raw) if buffer is None else buffer
        venv._tasks.observe(into, out=buffer)
        if isinstance(fresh, dict):
            for k in fresh:
                assert fresh[k].dtype == buffer[k].dtype == np.float32
                assert np.array_equal(fresh[k].view(np.uint32), buffer[k].view(np.uint32)), k
        else:
            assert fresh.dtype == buffer.dtype == np.float32
            assert np.array_equal(fresh.view(np.uint32), buffer.view(np.uint32))


def test_copy_false_returns_the_envs_own_arrays_and_copy_true_fresh_ones():
    own = usarsim.vector_env(4, state_only=True, flat=True, copy=False)
    a, _ = own.reset(seed=0)
    b = own.step(np.zeros((4, 4)))[0]
    c = own.step(np.ones((4, 4)))[0]
    assert b is c  # one array, overwritten by each step
    copied = usarsim.vector_env(4, state_only=True, flat=True)
    a, _ = copied.reset(seed=0)
    b = copied.step(np.zeros((4, 4)))[0]
    kept = b.copy()
    c = copied.step(np.ones((4, 4)))[0]
    assert b is not c and np.array_equal(b, kept) and not np.array_equal(b, c)


def test_same_step_final_observations_are_not_overwritten_by_the_next_episode():
    venv = usarsim.vector_env(3, "hover", max_steps=2, copy=False, autoreset_mode=AutoresetMode.SAME_STEP)
    venv.reset(seed=1)
    venv.step(np.full((3, 4), 0.5))
    obs, _, _, trunc, info = venv.step(np.full((3, 4), 0.5))
    assert trunc.all()
    final = np.stack([info["final_obs"][i]["position"] for i in range(3)])
    # The final positions are where the UAVs flew to, not the new episode's starts.
    assert not np.allclose(final, obs["position"])


def test_observe_into_names_what_is_wrong_with_a_buffer():
    venv = usarsim.vector_env(2)
    venv.reset(seed=0)
    good = venv._batch.observe()
    cases = [
        ({k: v for k, v in good.items() if k != "laser"}, "laser: missing"),
        ({**good, "position": np.zeros((3, 3))}, "position: shape [3, 3], expected [2, 3]"),
        ({**good, "velocity": np.zeros((2, 3), dtype=np.float32)}, "velocity: not a writable"),
        ({**good, "sonar": np.zeros((10, 2)).T}, "sonar: not C-contiguous"),
        ({**good, "touched": np.zeros(2)}, "touched: not a writable bool array"),
    ]
    for buffers, message in cases:
        with pytest.raises(ValueError, match=re.escape(message)):
            venv._batch.observe_into(buffers)
    readonly = {k: v.copy() for k, v in good.items()}
    readonly["battery"].flags.writeable = False
    with pytest.raises(ValueError, match="battery: not a writable"):
        venv._batch.observe_into(readonly)


def test_copy_must_be_a_bool():
    with pytest.raises(ValueError, match="copy: expected True or False"):
        usarsim.vector_env(2, copy="no")


def test_configure_rotor_speeds_remakes_the_envs_arrays():
    venv = usarsim.vector_env(2, robot="stsQuadrotor", state_only=True, flat=True, copy=False)
    a, _ = venv.reset(seed=0)
    width = a.shape[1]
    venv.configure(rotor_speeds=True)
    b, _ = venv.reset(seed=0)
    assert b.shape == (2, width + 4) and venv.step(np.zeros((2, 4)))[0].shape == (2, width + 4)


def test_the_angle_wrap_gives_numpys_remainder_bit_for_bit():
    """Observations and Hover's reward wrap angles with ``fmod`` (faster than ``%``): the same
    numbers, bit for bit, at the edges too (odd multiples of pi, -0, tiny negatives, huge
    values, infinities, NaN)."""
    from usarsim._task import _wrap

    rng = np.random.default_rng(5)
    edges = [np.pi, -np.pi, 3 * np.pi, -3 * np.pi, 0.0, -0.0, 2 * np.pi, -2 * np.pi,
             np.nextafter(-np.pi, 0), np.nextafter(np.pi, 0), -1e-300, 1e300, -1e300,
             np.inf, -np.inf, np.nan]
    x = np.concatenate([rng.uniform(-50, 50, 20000), rng.normal(0, 1e-12, 1000), edges])
    with np.errstate(invalid="ignore"):
        expected = (x + np.pi) % (2 * np.pi) - np.pi
        got = _wrap(x)
    assert got.tobytes() == expected.tobytes()
