"""Issue 24: the tasks' rewards and observations are worked out in Rust (``task_reward``,
``task_observe``); their NumPy definitions are kept and must give the same bits."""

import copy

import numpy as np
import pytest

import usarsim
from usarsim._core import LASER_BEAMS, SONARS, task_reward
from usarsim._task import Streams


def raw_state(rng, n, edge=True):
    """A raw observation as the batch gives, with values that probe the arithmetic: angles
    far outside [-pi, pi) and on its edges, positions beyond the clip, -0, NaN, empty
    batteries."""
    def col(w, scale):
        return rng.normal(size=(n, w)) * scale

    raw = {
        "position": col(3, 5.0), "velocity": col(3, 60.0), "attitude": col(3, 4.0),
        "angular_velocity": col(3, 80.0), "sonar": np.abs(col(SONARS, 4.0)), "laser": np.abs(col(LASER_BEAMS, 3.0)),
        "battery": rng.uniform(-0.2, 1.0, (n, 1)), "time": col(1, 1.0), "rotor_speeds": np.abs(col(4, 6e3)),
        "touched": rng.random(n) < 0.4, "crashed": rng.random(n) < 0.1,
    }
    if edge:
        raw["attitude"][:3, 2] = [np.pi, -np.pi, 3 * np.pi]
        raw["attitude"][3, :] = -0.0
        # Where the wrap's remainder changes its way (a call, or exact arithmetic): x + pi
        # at -2 pi, 2 pi and 4 pi, and an ulp either side.
        raw["attitude"][8, :] = [-3 * np.pi, np.nextafter(-3 * np.pi, 0), np.nextafter(-3 * np.pi, -np.inf)]
        raw["attitude"][9, :] = [np.nextafter(3 * np.pi, 0), np.nextafter(3 * np.pi, np.inf), 5 * np.pi]
        raw["attitude"][10, :] = [np.nextafter(np.pi, 0), np.nextafter(np.pi, np.inf), -1e3]
        raw["position"][4] = [2e4, -3e4, 0.0]
        raw["velocity"][5, 1] = np.nan
        raw["sonar"][6, 0] = -0.0
        raw["battery"][7, 0] = 0.0
    return raw


def bits(a):
    """An array's bits (so -0 differs from +0 and NaN equals NaN)."""
    a = np.ascontiguousarray(a)
    return a.view(np.uint32 if a.dtype == np.float32 else np.uint64) if a.dtype.kind == "f" else a


def same(a, b):
    if isinstance(a, dict):
        assert a.keys() == b.keys()
        for k in a:
            same(a[k], b[k])
        return
    assert a.dtype == b.dtype and a.shape == b.shape
    assert np.array_equal(bits(a), bits(b))


@pytest.mark.parametrize("task", ["hover", "waypoints"])
@pytest.mark.parametrize("state_only,flat", [(True, True), (False, False), (False, True), (True, False)])
def test_rewards_and_observations_in_rust_equal_their_numpy_definition(task, state_only, flat):
    n = 40
    env = usarsim.vector_env(n, task=task, state_only=state_only, flat=flat, max_steps=7)
    env.reset(seed=3)
    rust = env.unwrapped._tasks if hasattr(env, "unwrapped") else env._tasks
    rust.keys.append("rotor_speeds")
    # Rows with fewer waypoints than others, some near the last one.
    rust.count[::3] = 1
    numpy_ = copy.deepcopy(rust)
    reached = 0
    rng = np.random.default_rng(5)
    for step in range(30):
        raw = raw_state(rng, n, edge=step % 2 == 0)
        # Some rows right at their target, so that they reach it.
        near = rng.random(n) < 0.3
        k = np.minimum(rust.index, rust.count - 1)
        raw["position"][near] = rust.targets[np.arange(n), k][near] + rng.normal(size=(near.sum(), 3)) * 0.2
        live = rng.random(n) < 0.9 if step % 3 else None
        got, want = rust.reward(raw, live), numpy_._reward_numpy(raw, live)
        for a, b in zip(got[:3], want[:3]):
            same(a, b)
        same(got[3], want[3])
        reached += got[3]["reached"].sum()
        for name in ("index", "steps", "prev"):
            same(getattr(rust, name), getattr(numpy_, name))
        same(rust.observe(raw), numpy_._observe_numpy(raw))
        out = rust.observe(raw)  # written into an earlier result
        same(rust.observe(raw, out=out), numpy_._observe_numpy(raw))
        # Episodes that ended start over, as a reset does.
        ended = np.flatnonzero(got[1] | got[2])
        for t in (rust, numpy_):
            t.index[ended], t.steps[ended] = 0, 0
    if task == "waypoints":
        assert reached > 10, "few waypoints reached: the test would not see the bonus"


def test_bad_arrays_are_named():
    env = usarsim.vector_env(4, task="waypoints", state_only=True)
    env.reset(seed=0)
    t = env._tasks
    raw = raw_state(np.random.default_rng(0), 4, edge=False)
    with pytest.raises(ValueError, match="live: 3 rows, expected 4"):
        t.reward(raw, np.ones(3, dtype=bool))
    with pytest.raises(ValueError, match="position"):
        t.reward({**raw, "position": raw["position"][:, :2]})
    t.count[1] = 0
    with pytest.raises(ValueError, match="row 1: 0 waypoints"):
        t.reward(raw)
    with pytest.raises(ValueError, match="row 1: 0 waypoints"):
        t.observe(raw)
    t.count[1] = 3
    with pytest.raises(ValueError, match="out"):
        t.observe(raw, out=np.zeros((4, 2), np.float32))
    with pytest.raises(TypeError):
        task_reward(True)


def test_waypoints_and_random_starts_drawn_in_rust_follow_their_python_definition():
    env = usarsim.vector_env(3, map="arena", state_only=True)  # a map with obstacles
    m = env.map
    assert len(m.obstacles) > 0
    rows = [2, 0, 2, 1]  # a row twice: its second draws continue its stream
    near = np.array([[0.0, 0.0, -2.0], [3.0, -4.0, -2.0], [m.hi[0], 0.0, -2.0], [m.lo[0], 1.0, -2.0]])
    for kw in ({}, {"spacing": 1.5, "near": near, "radius": 5.0}, {"clearance": 0.3, "spacing": 0.1}):
        a, b = Streams.seeded(9, 3), Streams.seeded(9, 3)
        got, want = m.sample_rows(a, rows, 3, **kw), m._sample_rows_python(b, rows, 3, **kw)
        same(got, want)
        assert np.array_equal(a.drawn, b.drawn) and a.drawn.min() >= 9  # three draws per candidate
        assert all(m.free(p, kw.get("clearance", 1.0)).all() for p in got)
    with pytest.raises(ValueError, match="could not find 50 free places 5 m apart"):
        m.sample_rows(Streams.seeded(9, 3), [0], 50, spacing=5.0)


@pytest.mark.parametrize("start", [None, "random"])
def test_each_row_draws_its_own_waypoints_whoever_resets_with_it(start):
    # The rows' waypoints are drawn in Rust now (a NumPy generator each and a Python loop
    # cost 0.3-0.45 s per 1024 resets: docs/benchmarks-history.md, fifteenth round). A row's draws do
    # not depend on who else resets with it, and its waypoints keep their spacing.
    env = usarsim.vector_env(64, task="waypoints", state_only=True, start=start)
    env.reset(seed=4)
    alone = usarsim.vector_env(64, task="waypoints", state_only=True, start=start)
    alone.reset(seed=4)
    rows = np.arange(64)
    env._new_worlds(rows)
    for r in (5, 17):  # alone, each row draws what it drew with the others
        alone._new_worlds([r])
        assert np.array_equal(alone._tasks.targets[r], env._tasks.targets[r])
    t = env._tasks.targets
    assert len({tuple(np.round(t[r, 0], 9)) for r in rows}) == 64  # every row its own
    d = np.linalg.norm(t[:, 1, :2] - t[:, 0, :2], axis=1)
    assert d.min() >= 1.5


def test_hover_spawns_drawn_in_rust_follow_their_numpy_definition():
    env = usarsim.vector_env(6, task="hover", map="arena", state_only=True)
    t = env._tasks
    rows = np.array([4, 0, 5, 1, 4])  # a row twice draws the same twice, as Streams.doubles
    base = np.array([[0.0, 0.0, -2.0, 0.3], [3.0, -4.0, -1.0, 0.0], [5.0, 5.0, -0.7, 1.0],
                     [-3.0, 2.0, -2.5, -2.0], [1.0, 1.0, -0.9, 0.0]])
    for seed in range(20):
        a, b = Streams.seeded(seed, 6), Streams.seeded(seed, 6)
        got = usarsim._core.hover_spawns(a.keys, a.drawn, rows, base, [-1.0, -1.0, -0.5], [2.0, 2.0, 1.0],
                                         env.map.boxes(0.8), -0.5)
        same(got, t._hover_spawns_numpy(b.doubles(rows, 3), base))
        assert np.array_equal(a.drawn, b.drawn)
    assert not np.array_equal(got, base)  # some moved
    # With the task's arrays: each row's start becomes its target and its yaw the one to hold,
    # as NumPy's `targets[rows, 0] = base[:, :3]` and `hold_yaw[rows] = base[:, 3]` write them
    # (a repeated row: its last start); the other rows and waypoints are left as they were.
    targets, hold = np.full((6, 2, 3), 9.0), np.full(6, 9.0)
    want_t, want_h = targets.copy(), hold.copy()
    want_t[rows, 0] = base[:, :3]
    want_h[rows] = base[:, 3]
    a, b = Streams.seeded(3, 6), Streams.seeded(3, 6)
    got = usarsim._core.hover_spawns(a.keys, a.drawn, rows, base, [-1.0, -1.0, -0.5], [2.0, 2.0, 1.0],
                                     env.map.boxes(0.8), -0.5, targets, hold)
    same(got, t._hover_spawns_numpy(b.doubles(rows, 3), base))
    assert np.array_equal(targets, want_t) and np.array_equal(hold, want_h)
    with pytest.raises(ValueError, match=r"hover_spawns: targets \[5, 2, 3\]"):
        usarsim._core.hover_spawns(a.keys, a.drawn, rows, base, [-1.0, -1.0, -0.5], [2.0, 2.0, 1.0],
                                   env.map.boxes(0.8), -0.5, np.zeros((5, 2, 3)), hold)


def test_batch_resets_take_arrays_or_lists_and_name_bad_indices():
    env = usarsim.vector_env(3, task="hover", state_only=True)
    env.reset(seed=1)
    starts = np.tile([0.0, 0.0, -2.0, 0.0], (2, 1))
    env._batch.reset(np.array([2, 0]), np.array([5, 6], dtype=np.uint64), starts)
    env._batch.reset([2, 0], [5, 6], starts)
    with pytest.raises(ValueError, match=r"world index -1 out of range \(0..3\)"):
        env._batch.reset(np.array([-1, 0]), np.array([5, 6], dtype=np.uint64), starts)
    with pytest.raises(ValueError, match="world index 3 out of range"):
        env._batch.reset(np.array([3, 0]), [5, 6], starts)
    with pytest.raises(ValueError, match="listed twice"):
        env._batch.reset(np.array([1, 1]), [5, 6], starts)
