"""Many configurations as Ray tasks on a local Ray with 2 CPUs, gathered into one table."""

import sys
from pathlib import Path

import pytest

ray = pytest.importorskip("ray")
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "examples"))

from ray_sweep import sweep, table  # noqa: E402


@pytest.fixture(scope="module")
def local_ray():
    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False)
    yield
    ray.shutdown()


def test_sweep_runs_every_configuration_as_a_ray_task(local_ray):
    rows = sweep(maps=("empty_room", "arena"), noises=(0.0,), seeds=range(2))
    assert [(r["map"], r["seed"]) for r in rows] == [
        ("empty_room", 0), ("empty_room", 1), ("arena", 0), ("arena", 1)]
    assert all(r["steps"] > 0 for r in rows)
    # The controller reaches waypoints in the empty room.
    assert sum(r["waypoints"] for r in rows if r["map"] == "empty_room") >= 2
    text = table(rows)
    assert text.splitlines()[0].split()[:3] == ["map", "noise", "seed"] and len(text.splitlines()) == 5
    # Same configuration, same result: tasks are deterministic wherever they run.
    again = sweep(maps=("empty_room",), noises=(0.0,), seeds=range(1))
    assert again[0]["return"] == rows[0]["return"]
