"""benchmarks/steps_per_second.py --compare: argument errors, and a tiny real A/B run."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

import usarsim

SCRIPT = Path(__file__).resolve().parents[1] / "benchmarks" / "steps_per_second.py"


def run(*args, timeout=60):
    # The environment (PYTHONPATH included) is this test's: build A is the usarsim it imports.
    return subprocess.run([sys.executable, str(SCRIPT), *args], capture_output=True, text=True,
                          timeout=timeout, env=dict(os.environ))


@pytest.mark.parametrize("args, message", [
    (["1", "--compare", "{missing}"], "argument --compare: {missing} does not exist"),
    (["1", "--compare", "{empty}"], "argument --compare: no usarsim package"),
    (["1", "--compare", "{junk_whl}"], "argument --compare: cannot unzip {junk_whl}"),
    (["abc", "--compare", "{pkg}"], "argument seconds: not a number"),
    (["1", "--compare", "{pkg}", "--pairs", "0"], "argument --pairs: must be at least 1"),
    (["1", "--compare", "{pkg}", "--cases", "bogus"], "argument --cases: unknown case(s) bogus"),
    (["1", "--pairs", "2"], "--pairs and --cases apply only with --compare"),
])
def test_bad_arguments_exit_2_with_a_message(tmp_path, args, message):
    (tmp_path / "empty").mkdir()
    (tmp_path / "junk.whl").write_text("not a zip")
    paths = {"missing": str(tmp_path / "no-such-build"), "empty": str(tmp_path / "empty"),
             "junk_whl": str(tmp_path / "junk.whl"), "pkg": str(Path(usarsim.__file__).parents[1])}
    proc = run(*[a.format(**paths) for a in args])
    assert proc.returncode == 2, proc.stderr
    assert message.format(**paths) in proc.stderr
    assert "Traceback" not in proc.stderr
    assert proc.stdout == ""


def test_compare_the_package_with_itself():
    pkg = str(Path(usarsim.__file__).resolve().parents[1])
    proc = run("0.2", "--compare", pkg, "--pairs", "1", "--cases", "state-256")
    assert proc.returncode == 0, proc.stderr
    out = proc.stdout
    here = os.path.realpath(usarsim.__file__)
    assert f"A: {here}" in out and f"B: {here}" in out
    assert "A and B imported the same file" in out
    assert "state-256 (vector env, 256 UAVs, state): median UAV-steps/s A " in out
    assert "B/A ratio per pair, min / median / max: " in out


def _touched_share(actions, num=128, steps=200):
    """Share of UAV-steps touching something in the last 100 of `steps` state-only steps."""
    import numpy as np

    venv = usarsim.vector_env(num, state_only=True, flat=True)
    venv.reset(seed=0)
    touched = 0
    for n in range(steps):
        info = venv.step(actions(n))[4]
        if n >= steps - 100:
            touched += int(np.count_nonzero(info["touched"]))
    venv.close()
    return touched / (100 * num)


def test_random_actions_are_fresh_and_pressed_ones_fly_into_walls():
    # The speed cases' "random actions" were 8 fixed arrays taken in turn: every UAV repeated
    # set-points whose mean is not zero, flew into a wall and slid along it (a third of the
    # UAV-steps touching after 100 steps), so the figure measured contact, not random flight.
    import importlib.util

    import numpy as np

    spec = importlib.util.spec_from_file_location("steps_per_second", SCRIPT)
    bench = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bench)
    random = bench._actions(np.random.default_rng(0), 128)
    first, second = random(0), random(0)
    assert first.shape == (128, 4) and not np.array_equal(first, second)
    pressed = bench._actions(np.random.default_rng(0), 128, pressed=True)
    assert np.array_equal(pressed(3), pressed(11))
    assert _touched_share(random) < 0.1
    assert _touched_share(pressed) > 0.25
