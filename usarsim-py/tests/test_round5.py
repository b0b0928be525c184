"""Issue 24, fifth round: autoresets that cost little — one random stream per sub-environment
drawn for all at once (``usarsim._task.Streams``), and worlds reset in place without copying
the map."""

import pickle
import warnings

import gymnasium as gym
import numpy as np
import pytest

import usarsim
from usarsim._task import Streams


def test_each_row_draws_its_own_stream_whatever_else_draws():
    together = Streams.seeded(7, 6)
    a = together.draw(np.arange(6), 3)
    assert a.shape == (6, 3) and a.dtype == np.uint64
    assert len(np.unique(a)) == 18  # no two rows (and no two draws) alike
    for i in range(6):  # a row alone draws what it drew with the others
        assert np.array_equal(Streams.seeded(7, 6).draw([i], 3)[0], a[i])
    # A stream continues: three draws then two are its first five.
    s = Streams.seeded(7, 6)
    five = np.concatenate([s.draw([2], 3)[0], s.draw([2], 2)[0]])
    assert np.array_equal(five, Streams.seeded(7, 6).draw([2], 5)[0])
    # Set back to a recorded point, it draws the same again.
    keys, drawn = s.state()
    again = Streams(keys, drawn).draw([2, 4], 4)
    assert np.array_equal(again, s.draw([2, 4], 4))
    # Another seed, other draws; seeds are 63-bit integers; doubles in [0, 1).
    assert not np.array_equal(Streams.seeded(8, 6).draw(np.arange(6), 3), a)
    seeds = Streams.seeded(7, 6).seeds(range(6))
    assert seeds.dtype == np.uint64 and (seeds < 2**63).all() and len(set(seeds.tolist())) == 6
    u = Streams.seeded(1, 1000).doubles(np.arange(1000), 3)
    assert u.min() >= 0 and u.max() < 1 and abs(u.mean() - 0.5) < 0.02


def test_the_streams_draw_in_rust_what_their_numpy_definition_gives():
    # Streams.draw runs in Rust (usarsim._core.stream_draws); its NumPy definition is kept.
    a, b = Streams.seeded(11, 50), Streams.seeded(11, 50)
    for rows, k in (([0, 49, 3], 3), (np.arange(50), 1), ([7, 7, 2], 2), ([], 4), (range(5), 2)):
        assert np.array_equal(a.draw(rows, k), b._draw_numpy(rows, k))
        assert np.array_equal(a.drawn, b.drawn)
    with pytest.raises(ValueError, match="row 50 is not in 0..50"):
        a.draw([50], 1)
    assert np.array_equal(a.drawn, b.drawn)  # a bad row draws nothing


def test_seeds_of_any_size_draw_without_overflow_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for seed in (0, 1, 2**63, 2**64 - 1, 2**80 + 3):
            s = Streams.seeded(seed, 3)
            s.draw([0, 1, 2], 4)
            s.seeds([0, 2])
            s.doubles([1], 2)


@pytest.mark.parametrize("task", ["hover", "waypoints"])
def test_sub_envs_start_differently_and_repeat_under_the_seed(task):
    def starts(seed):
        venv = usarsim.vector_env(6, task, map="arena", max_steps=2)
        obs, _ = venv.reset(seed=seed)
        firsts = [obs["position"].copy()]
        for _ in range(4):  # two autoresets of every sub-env
            obs, *_ = venv.step(np.zeros((6, 4)))
            firsts.append(obs["position"].copy())
        return np.array(firsts), venv._tasks.targets.copy()

    (a, ta), (b, tb), (c, tc) = starts(3), starts(3), starts(4)
    assert np.array_equal(a, b) and np.array_equal(ta, tb)
    if task == "hover":  # spawned around the start, each sub-env at its own offset
        assert not np.array_equal(a, c)
        assert len({tuple(p) for p in a[0].round(6)}) == 6
        # Episode after episode, a sub-env starts somewhere new (its stream goes on).
        assert not np.array_equal(a[0], a[3])
    else:  # from the map's start to random waypoints, each sub-env its own
        assert not np.array_equal(ta, tc)
        assert len({tuple(t.ravel()) for t in ta.round(6)}) == 6


def test_a_copy_made_after_many_autoresets_continues_identically():
    venv = usarsim.vector_env(64, "hover", max_steps=3, state_only=True, flat=True)
    venv.reset(seed=9)
    rng = np.random.default_rng(1)
    for _ in range(20):
        venv.step(rng.uniform(-1, 1, (64, 4)))
    twin = pickle.loads(pickle.dumps(venv))
    assert len(pickle.dumps(venv)) < 64 * 4 * 8 * 8 + 20_000  # a few steps of actions, not the run
    for _ in range(8):
        a = rng.uniform(-1, 1, (64, 4))
        x, y = venv.step(a), twin.step(a)
        assert np.array_equal(x[0], y[0]) and np.array_equal(x[1], y[1]) and np.array_equal(x[3], y[3])


# Observations written by each world into the env's arrays, on the worker threads, in the
# step's own pass (Batch.step(..., out=...)).


def _twins(make):
    a, b = make(), make()
    a.reset(seed=4)
    b.reset(seed=4)
    return a, b


@pytest.mark.parametrize("options", [{}, {"state_only": True}, {"robot": "stsQuadrotor"}])
def test_observations_written_during_the_step_equal_those_read_after_it(options):
    a, b = _twins(lambda: usarsim.vector_env(9, max_steps=5, **options))
    if "robot" in options:  # with the rotor speeds too
        for env in (a, b):
            env._batch.configure(rotor_speeds=True)
            env._batch.reset(list(range(9)), [1] * 9, np.tile([0.0, 0.0, -2.0, 0.0], (9, 1)))
    out = {k: np.full_like(v, 7) for k, v in b._batch.observe().items()}
    rng = np.random.default_rng(0)
    for k in range(12):
        act = rng.uniform(-1, 1, (9, 4))
        reset = ([1, 4], [k, k + 1], np.tile([0.0, 0.0, -2.0, 0.0], (2, 1))) if k % 4 == 3 else None
        a._batch.step(act, reset)
        expected = a._batch.observe()
        b._batch.step(act, reset, out=out)
        assert set(out) == set(expected)
        for key in expected:
            assert out[key].dtype == expected[key].dtype
            assert np.array_equal(out[key], expected[key]), key
    if "robot" in options:
        assert np.all(out["rotor_speeds"] > 0)


def test_several_uavs_per_world_write_their_own_rows():
    env = usarsim.multi_uav(3)
    env.reset(seed=2)
    batch = env._batch
    out = {k: np.zeros_like(v) for k, v in batch.observe().items()}
    batch.step(np.array([[1.0, 0, 0, 0], [0, 1.0, 0, 0], [0, 0, 0.5, 0]]), out=out)
    assert np.array_equal(out["position"], batch.observe()["position"])
    assert len({tuple(p) for p in out["position"].round(6)}) == 3


def test_a_bad_out_is_named_and_nothing_steps():
    venv = usarsim.vector_env(4)
    venv.reset(seed=0)
    batch = venv._batch
    good = batch.observe()
    t = batch.time(0)
    cases = {
        "laser": lambda o: o.pop("laser"),
        "sonar": lambda o: o.__setitem__("sonar", np.zeros((4, 9))),
        "position": lambda o: o.__setitem__("position", np.zeros((4, 3), np.float32)),
        "velocity": lambda o: o.__setitem__("velocity", np.asfortranarray(np.zeros((4, 3)))),
        "touched": lambda o: o.__setitem__("touched", np.zeros(4)),
    }
    for key, spoil in cases.items():
        out = {k: v.copy() for k, v in good.items()}
        spoil(out)
        with pytest.raises(ValueError, match=f"step: out: {key}"):
            batch.step(np.zeros((4, 4)), out=out)
        assert batch.time(0) == t  # checked before anything stepped
    frozen = {k: v.copy() for k, v in good.items()}
    frozen["battery"].flags.writeable = False
    with pytest.raises(ValueError, match="step: out: battery: not a writable"):
        batch.step(np.zeros((4, 4)), out=frozen)


def test_every_world_of_a_batch_steps_once_per_step_with_its_own_actions():
    # The threads share the worlds out in pieces (`par_each` in src/core.rs): a piece skipped
    # or stepped twice would leave its worlds at another time than the others, and a piece
    # given another's rows of actions would move other UAVs.
    n = 37  # shared out on 2 cores or more (at least core::PARALLEL_WORLDS), in pieces
    venv = usarsim.vector_env(n, "hover", max_steps=3, state_only=True)
    one = usarsim.vector_env(1, "hover", max_steps=3, state_only=True)
    venv.reset(seed=5)
    one.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(7):  # with two autoresets of every world
        a = rng.uniform(-1, 1, (n, 4))
        obs, *_ = venv.step(a)
        first, *_ = one.step(a[:1])
        assert [venv._batch.time(i) for i in range(n)] == [one._batch.time(0)] * n
        assert all(np.array_equal(obs[k][0], first[k][0]) for k in obs)
    venv.reset(seed=5)
    for k in (0, 18, n - 1):
        a = np.zeros((n, 4))
        a[k, 0] = 1.0  # full speed forward: only UAV k moves
        before = venv._batch.observe()["position"]
        venv.step(a)
        moved = np.linalg.norm(venv._batch.observe()["position"] - before, axis=1) > 0.05
        assert np.flatnonzero(moved).tolist() == [k]


def _step_in_child(q):
    venv = usarsim.vector_env(32, state_only=True, flat=True)  # enough worlds for the threads
    venv.reset(seed=0)
    for _ in range(3):
        venv.step(np.zeros((32, 4)))
    q.put(venv._batch.time(7))


@pytest.mark.skipif("fork" not in __import__("multiprocessing").get_all_start_methods(), reason="no fork here")
def test_a_process_forked_after_stepping_steps_its_own_worlds():
    # The batch's worker threads are kept between steps; a forked child (Gymnasium's
    # AsyncVectorEnv, multiprocessing's default on Linux) has none of them and must start
    # its own, not wait forever for its parent's.
    import multiprocessing as mp

    parent = usarsim.vector_env(32, state_only=True, flat=True)
    parent.reset(seed=0)
    parent.step(np.zeros((32, 4)))  # the threads exist now
    ctx = mp.get_context("fork")
    q = ctx.Queue()
    child = ctx.Process(target=_step_in_child, args=(q,))
    child.start()
    try:
        assert q.get(timeout=20) == pytest.approx(0.4)  # one period at the reset, three steps
    finally:
        child.join(10)
        if child.is_alive():
            child.kill()
    assert child.exitcode == 0
    parent.step(np.zeros((32, 4)))
    assert parent._batch.time(7) == pytest.approx(0.3)


@pytest.mark.parametrize("robot", ["USARBot.stsAirRobot", "USARBot.stsQuadrotor"])
def test_a_world_reset_in_place_flies_as_a_new_one_bit_for_bit(robot):
    # A reset keeps the world's UAVs' INITs (only their poses change) and starts their client
    # state anew: after an episode flown into the walls and floor (contact, for the quadrotor crashes), world 0 reset
    # with a seed and starts observes and flies exactly as a new batch made with them, both
    # UAVs of it (the second one's INIT names it UAV1); world 1 flies on untouched.
    starts = np.array([[0.0, 0.0, -1.5, 0.0], [1.0, 0.5, -1.5, 0.3]] * 2)
    old = usarsim.Batch("empty_room", robot, [3, 4], starts, uavs_per_world=2)
    rng = np.random.default_rng(1)
    for _ in range(60):
        old.step(rng.uniform(-1, 1, (4, 4)))
    for _ in range(20):  # then down onto the floor
        old.step(np.tile([0.3, 0.0, -1.0, 0.5], (4, 1)))
    assert old.observe()["touched"][:2].all() or old.observe()["crashed"][:2].all()
    again = np.array([[0.5, -0.5, -1.2, 1.0], [-1.0, 0.0, -2.0, -0.4]])
    old.reset([0], [11], again)
    fresh = usarsim.Batch("empty_room", robot, [11], again, uavs_per_world=2)
    for k in range(12):
        a, b = old.observe(), fresh.observe()
        for key in b:
            assert np.array_equal(a[key][:2], b[key]), (k, key)
        act = rng.uniform(-1, 1, (4, 4))
        old.step(act)
        fresh.step(act[:2])


def test_a_batchs_arrays_name_the_first_value_not_finite_laid_out_either_way():
    # Contiguous arrays are read as one slice, others row by row: the same error either way,
    # naming the row and column, and the batch is left as it was.
    starts = np.array([[0.0, 0.0, -1.5, 0.0], [1.0, 0.5, -1.5, 0.3]])
    batch = usarsim.Batch("empty_room", "USARBot.stsAirRobot", [3, 4], starts)
    before = batch.observe()
    bad = np.array([[0.5, -0.5, -1.2, 1.0], [-1.0, 0.0, np.inf, -0.4]])
    for layout in (bad, np.asfortranarray(bad), np.hstack([bad, bad])[:, :4]):
        with pytest.raises(ValueError, match=r"starts: row 1, column 2 is not finite \(inf\)"):
            batch.reset([0, 1], [5, 6], layout)
        actions = np.zeros((2, 4))
        actions[1, 3] = np.nan
        actions = actions if layout is bad else np.asfortranarray(actions)
        with pytest.raises(ValueError, match=r"action: row 1, column 3 is not finite \(NaN\)"):
            batch.step(actions)
    after = batch.observe()
    assert all(np.array_equal(before[k], after[k]) for k in before)


def _unfused(env):
    """`env` stepping the batch, then working out the task's rewards and observations
    after the pass (the way before `Batch.step_task`)."""

    def step_task(a, reset, live):
        raw = env._step_raw(a, reset)
        return (raw, *env._tasks.reward(raw, live), False)

    env._step_task = step_task
    return env


@pytest.mark.parametrize("task", ["waypoints", "hover"])
@pytest.mark.parametrize("options", [{"state_only": True, "flat": True}, {},
                                     {"autoreset_mode": gym.vector.AutoresetMode.SAME_STEP, "flat": True}])
def test_the_task_worked_out_in_the_steps_pass_equals_it_worked_out_after(task, options):
    # Short episodes: resets in the pass (NEXT_STEP) and after it (SAME_STEP), waypoints
    # reached and not; 130 worlds: shared out among the threads in pieces of several worlds
    # (of 3 on 2 cores).
    n = 130
    make = lambda: usarsim.vector_env(n, task, max_steps=6, waypoint_radius=1.5, **options)  # noqa: E731
    fused, after = make(), _unfused(make())
    rng = np.random.default_rng(3)
    for env in (fused, after):
        env.reset(seed=9)
    for _ in range(40):
        act = rng.uniform(-1, 1, (n, 4))
        one, two = fused.step(act), after.step(act)
        for x, y in zip(one[:4], two[:4]):
            x, y = (x, y) if isinstance(x, dict) else ({"": x}, {"": y})
            assert x.keys() == y.keys()
            for k in x:
                assert x[k].dtype == y[k].dtype and np.array_equal(x[k], y[k]), k
        for k in ("touched", "crashed", "reached", "waypoints_reached"):
            assert np.array_equal(one[4][k], two[4][k]), k
    assert fused._tasks.index.any() or task == "hover"


def test_a_bad_task_array_is_named_and_nothing_steps():
    venv = usarsim.vector_env(4, state_only=True, flat=True)
    venv.reset(seed=0)
    venv.step(np.zeros((4, 4)))
    batch, tasks, t = venv._batch, venv._tasks, venv._batch.time(0)
    live = np.ones(4, dtype=bool)
    spoilt = {
        "live": (lambda: (np.ones(3, dtype=bool), venv._obs), "live: 3 rows"),
        "out": (lambda: (live, np.zeros((4, 2), np.float32)), "out: shape"),
    }
    for name, (make, message) in spoilt.items():
        live_arg, out = make()
        with pytest.raises(ValueError, match=message):
            tasks.step(batch, np.zeros((4, 4)), None, venv._raw, live_arg, out)
        assert batch.time(0) == t, name  # checked before anything stepped
    sonar = dict(venv._raw, sonar=np.zeros((4, 10)))
    tasks.keys = [*tasks.keys, "sonar"]
    with pytest.raises(ValueError, match='does not observe "sonar"'):
        tasks.step(batch, np.zeros((4, 4)), None, sonar, live, np.zeros((4, 29), np.float32))
    assert batch.time(0) == t
