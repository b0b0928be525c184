"""UAV-steps per second and per CPU-second (figures for BENCHMARKS.md).

    python benchmarks/steps_per_second.py [seconds per case]

1 UAV: gymnasium.make("usarsim/Waypoints-v0") stepped from Python (with Gymnasium's
wrappers, as users run it). N UAVs: usarsim.vector_env(N), one Rust call per step; a UAV-step
is one UAV advanced one control period (0.1 s simulated, 20 physics ticks). "full": the
stsAirRobot with every sensor (228-beam laser, 10 sonars) and the Dict observation; "state":
``state_only=True, flat=True`` (no range sensors; one float32 Box). Random actions: fresh
set-points drawn uniformly every step, as a random policy gives them; "pressed": every UAV
repeats the same 8 random set-points, flies into a wall, the floor or the ceiling and slides
along it (the contact-heavy case; the ``hover-state-1024`` case of --compare: zero actions,
every UAV hovering); episodes end and autoreset (NEXT_STEP) as they come. "autoreset step":
one step in which every sub-environment resets (episodes of 1 step, zero actions: the cheapest normal step there is),
against a normal step, full and state-only (a reset flies the world until every sensor has
read once: three control periods with the 0.3 s laser, one without the range sensors).
"autoreset in flight": the same in Hover episodes of 50 steps flown with the random actions
(the normal step the speed cases time; every sub-env ends in the same step), and in Waypoints
episodes (state-only), whose resets draw new random waypoints.

Per CPU-second is the process's CPU time (user + system, all threads): on a machine shared
with other work it is the fairer figure; wall-clock UAV-steps/s depends on the free cores.

Paired A/B comparison of two builds of the package (see --help):

    python benchmarks/steps_per_second.py 3 --compare OTHER [--pairs 5] [--cases state-1024,...]
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
import zipfile

# gymnasium, numpy and usarsim are imported by the functions that time a case, so that
# --compare's parent process (which only starts subprocesses) does not import a build at all.


def clocks():
    # process_time: user + system of every thread, at nanosecond resolution (os.times() counts
    # in 10 ms ticks, too coarse for one step).
    return time.perf_counter(), time.process_time()


def single(seconds):
    import gymnasium
    import numpy as np

    import usarsim  # noqa: F401  (registers the environments)

    env = gymnasium.make("usarsim/Waypoints-v0")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    n, (w0, c0) = 0, clocks()
    while clocks()[0] - w0 < seconds:
        _, _, term, trunc, _ = env.step(rng.uniform(-1, 1, 4).astype(np.float32))
        n += 1
        if term or trunc:
            env.reset()
    w1, c1 = clocks()
    return n / (w1 - w0), n / max(c1 - c0, 1e-9)


def vector(num, seconds, hover=False, pressed=False, **options):
    import numpy as np

    import usarsim

    venv = usarsim.vector_env(num, **options)
    venv.reset(seed=0)
    rng = np.random.default_rng(0)
    actions = _actions(rng, num, hover, pressed)
    n, (w0, c0) = 0, clocks()
    while clocks()[0] - w0 < seconds or n == 0:
        venv.step(actions(n))
        n += 1
    w1, c1 = clocks()
    return n * num / (w1 - w0), n * num / max(c1 - c0, 1e-9)


def _actions(rng, num, hover=False, pressed=False):
    """The actions of step n: `actions(n)`. Random: fresh set-points drawn uniformly every
    step, as a random policy (the peers' ``action_space.sample()``) gives them, drawn in the
    timed loop as a policy's would be. `hover`: zero actions, the cheapest step there is (no
    move, no contact). `pressed`: every UAV repeats the same 8 random set-points, whose mean
    is not zero, so it flies straight into a wall, the floor or the ceiling and slides along
    it (some 40 % of the UAV-steps touch something after 200 steps, against 3-4 % with fresh
    actions): the contact-heavy case (this was the random case before 2026-11-29)."""
    import numpy as np

    if hover:
        zeros = np.zeros((num, 4))
        return lambda n: zeros
    if pressed:
        cycle = [rng.uniform(-1, 1, (num, 4)) for _ in range(8)]
        return lambda n: cycle[n % 8]
    return lambda n: rng.uniform(-1, 1, (num, 4))


def _medians(times):
    """(wall, CPU) medians of (wall, CPU) pairs."""
    return statistics.median(w for w, _ in times), statistics.median(c for _, c in times)


def autoreset(num, repeats=20, seconds=None, **options):
    """(wall, CPU) seconds of a normal step and of a step where all `num` sub-envs reset
    (medians). With `seconds`, repeats at least `repeats` times and until `seconds` have
    passed."""
    import numpy as np

    import usarsim

    venv = usarsim.vector_env(num, "hover", max_steps=1, **options)
    venv.reset(seed=0)
    a = np.zeros((num, 4))
    normal, resetting = [], []
    start = time.perf_counter()
    while len(normal) < repeats or (seconds is not None and time.perf_counter() - start < seconds):
        for record in (normal, resetting):  # max_steps=1 ends every episode: a normal step,
            w0, c0 = clocks()  # then (NEXT_STEP) a step where every sub-env resets
            venv.step(a)
            w1, c1 = clocks()
            record.append((w1 - w0, c1 - c0))
    return _medians(normal), _medians(resetting)


def autoreset_flying(num, episode=50, episodes=6, task="hover", **options):
    """(wall, CPU) seconds of a normal step and of a step where all `num` sub-envs reset
    (medians), in `task` episodes of `episode` steps flown with the speed cases' random
    actions: every sub-env ends in the same step, and the next resets them all (Waypoints:
    each reset draws new random waypoints)."""
    import numpy as np

    import usarsim

    venv = usarsim.vector_env(num, task, max_steps=episode, **options)
    venv.reset(seed=0)
    actions = _actions(np.random.default_rng(0), num)
    normal, resetting = [], []
    ended = 0
    for n in range(episode * episodes + 1):
        a = actions(n)
        w0, c0 = clocks()
        _, _, terminated, truncated, _ = venv.step(a)
        w1, c1 = clocks()
        if ended == 0:
            normal.append((w1 - w0, c1 - c0))
        elif ended == num:
            resetting.append((w1 - w0, c1 - c0))
        ended = int((terminated | truncated).sum())
    return _medians(normal), _medians(resetting)


STATE = {"state_only": True, "flat": True}


def _autoreset_rate(num, seconds, **options):
    # UAV-steps/s of the steps in which every sub-environment resets (higher is faster, like
    # the other cases).
    _, (rw, rc) = autoreset(num, seconds=seconds, **options)
    return num / rw, num / max(rc, 1e-9)


CASES = {
    "single-full": ("1 UAV (gymnasium.make), full", single),
    "full-16": ("vector env, 16 UAVs, full", lambda s: vector(16, s)),
    "state-16": ("vector env, 16 UAVs, state", lambda s: vector(16, s, **STATE)),
    "full-256": ("vector env, 256 UAVs, full", lambda s: vector(256, s)),
    "state-256": ("vector env, 256 UAVs, state", lambda s: vector(256, s, **STATE)),
    "full-1024": ("vector env, 1024 UAVs, full", lambda s: vector(1024, s)),
    "state-1024": ("vector env, 1024 UAVs, state", lambda s: vector(1024, s, **STATE)),
    "hover-state-1024": ("vector env, 1024 UAVs, state, zero actions", lambda s: vector(1024, s, hover=True, **STATE)),
    "pressed-full-1024": ("vector env, 1024 UAVs, full, pressed", lambda s: vector(1024, s, pressed=True)),
    "pressed-state-1024": ("vector env, 1024 UAVs, state, pressed", lambda s: vector(1024, s, pressed=True, **STATE)),
    "autoreset-full-256": ("resetting steps, 256 UAVs, full", lambda s: _autoreset_rate(256, s)),
    "autoreset-state-256": ("resetting steps, 256 UAVs, state", lambda s: _autoreset_rate(256, s, **STATE)),
    "autoreset-full-1024": ("resetting steps, 1024 UAVs, full", lambda s: _autoreset_rate(1024, s)),
    "autoreset-state-1024": ("resetting steps, 1024 UAVs, state", lambda s: _autoreset_rate(1024, s, **STATE)),
}
DEFAULT_CASES = ["full-16", "state-16", "full-256", "state-256", "full-1024", "state-1024",
                 "pressed-full-1024", "pressed-state-1024"]


def run_default(seconds):
    """The benchmark without --compare: every case once, in this process."""
    print(f"cores: {os.cpu_count()}, load average {os.getloadavg()[0]:.1f} at the start")
    for case in ["single-full", *DEFAULT_CASES]:
        name, fn = CASES[case]
        wall, cpu = fn(seconds)
        print(f"{name:34s} {wall:10.0f} UAV-steps/s   {cpu:10.0f} per CPU-second")
    for n in (256, 1024):
        for kind, options in (("full", {}), ("state", STATE)):
            (nw, nc), (rw, rc) = autoreset(n, **options)
            print(f"autoreset, {n:4d} UAVs, {kind}: normal step {nw * 1e3:6.1f} ms ({nc * 1e3:5.1f} CPU), "
                  f"resetting all {rw * 1e3:6.1f} ms ({rc * 1e3:5.1f} CPU): {rw / nw:.2f}x wall, {rc / nc:.2f}x CPU")
    for kind, task, options in (("full", "hover", {}), ("state", "hover", STATE), ("state", "waypoints", STATE)):
        (nw, nc), (rw, rc) = autoreset_flying(1024, task=task, **options)
        print(f"autoreset in flight, 1024 UAVs, {kind}, {task}: normal step {nw * 1e3:6.1f} ms ({nc * 1e3:5.1f} CPU), "
              f"resetting all {rw * 1e3:6.1f} ms ({rc * 1e3:5.1f} CPU): {rw / nw:.2f}x wall, {rc / nc:.2f}x CPU")


# --- paired A/B comparison (--compare) ------------------------------------------------------


def run_child(case, seconds):
    """One case in this (fresh) process; one JSON line: which usarsim it ran, and the figures."""
    import usarsim

    wall, cpu = CASES[case][1](seconds)
    print(json.dumps({"file": os.path.realpath(usarsim.__file__), "wall": wall, "cpu": cpu}))


def _child_env(prepend):
    env = dict(os.environ)
    if prepend is not None:
        old = env.get("PYTHONPATH")
        env["PYTHONPATH"] = prepend + (os.pathsep + old if old else "")
    return env


def _measure(case, seconds, prepend, label):
    cmd = [sys.executable, os.path.abspath(__file__), "--child", case, str(seconds)]
    proc = subprocess.run(cmd, env=_child_env(prepend), capture_output=True, text=True)
    lines = proc.stdout.strip().splitlines()
    try:
        if proc.returncode != 0:
            raise ValueError
        return json.loads(lines[-1])
    except (ValueError, IndexError):
        tail = "\n".join((proc.stderr or proc.stdout).strip().splitlines()[-15:])
        sys.exit(f"steps_per_second.py: error: build {label}, case {case}: the subprocess failed "
                 f"(exit {proc.returncode}):\n{tail}")


def _fmt(x):
    return f"{x:,.0f}"


def run_compare(seconds, other, pairs, cases, shown_as=None):
    print(f"cores: {os.cpu_count()}, load average {os.getloadavg()[0]:.1f} at the start")
    print(f"paired A/B: {pairs} pair(s) per case, {seconds:g} s per run, each run a fresh process; "
          "order A,B then B,A alternately")
    other_real = os.path.realpath(other)
    files = {"A": set(), "B": set()}
    for case in cases:
        runs = {"A": [], "B": []}
        for i in range(pairs):
            for label in ("AB" if i % 2 == 0 else "BA"):
                r = _measure(case, seconds, other if label == "B" else None, label)
                if label == "B" and not r["file"].startswith(other_real + os.sep):
                    sys.exit(f"steps_per_second.py: error: argument --compare: build B imported {r['file']}, "
                             f"not the usarsim in {shown_as or other}")
                if not files[label]:
                    origin = "this interpreter's PYTHONPATH" if label == "A" else f"--compare {shown_as or other}"
                    print(f"{label}: {r['file']}  ({origin})")
                files[label].add(r["file"])
                runs[label].append(r)
            if i == 0 and case == cases[0] and files["A"] == files["B"]:
                print("note: A and B imported the same file: the ratios show only the noise")
        name = CASES[case][0]
        ratios = [b["wall"] / a["wall"] for a, b in zip(runs["A"], runs["B"])]
        cpu_ratios = [b["cpu"] / a["cpu"] for a, b in zip(runs["A"], runs["B"])]
        med_a = statistics.median(r["wall"] for r in runs["A"])
        med_b = statistics.median(r["wall"] for r in runs["B"])
        print(f"{case} ({name}): median UAV-steps/s A {_fmt(med_a)}, B {_fmt(med_b)}")
        print(f"  B/A ratio per pair, min / median / max: {min(ratios):.3f} / {statistics.median(ratios):.3f} / "
              f"{max(ratios):.3f} (per CPU-second: median {statistics.median(cpu_ratios):.3f})", flush=True)
    for label in ("A", "B"):
        if len(files[label]) > 1:
            print(f"warning: build {label}'s runs imported different files: {sorted(files[label])}")
    print(f"load average {os.getloadavg()[0]:.1f} at the end")


def _positive_float(text):
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise argparse.ArgumentTypeError(f"must be a positive number of seconds, not {text!r}")
    return value


def _positive_int(text):
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a whole number: {text!r}") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, not {text!r}")
    return value


def _case_list(text):
    names = [c.strip() for c in text.split(",") if c.strip()]
    bad = [c for c in names if c not in CASES]
    if bad or not names:
        raise argparse.ArgumentTypeError(f"unknown case(s) {', '.join(bad) or repr(text)}; "
                                         f"choose from: {', '.join(CASES)}")
    return names


def _resolve_other(parser, other, tmp):
    """The directory to put first on PYTHONPATH for build B (a .whl is unzipped into `tmp`)."""
    if not os.path.exists(other):
        parser.error(f"argument --compare: {other} does not exist")
    if os.path.isfile(other):
        if not other.endswith(".whl"):
            parser.error(f"argument --compare: {other} is a file but not a .whl")
        try:
            with zipfile.ZipFile(other) as whl:
                whl.extractall(tmp)
        except (zipfile.BadZipFile, OSError) as e:
            parser.error(f"argument --compare: cannot unzip {other}: {e}")
        other = tmp
    elif not os.path.isdir(other):
        parser.error(f"argument --compare: {other} is neither a directory nor a .whl")
    if not os.path.isfile(os.path.join(other, "usarsim", "__init__.py")):
        where = "the wheel" if other == tmp else other
        parser.error(f"argument --compare: no usarsim package (usarsim/__init__.py) in {where}")
    return other


def main(argv=None):
    parser = argparse.ArgumentParser(
        prog="steps_per_second.py",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "UAV-steps per second of the usarsim package (a UAV-step: one UAV advanced one\n"
            "control period, 0.1 s simulated). Without --compare: every case once in this\n"
            "process, wall-clock UAV-steps/s and UAV-steps per CPU-second, then the autoreset\n"
            "cases (a step where every sub-environment resets, against a normal step)."),
        epilog=(
            "--compare: a paired A/B comparison of two builds of the package. A is the usarsim\n"
            "this interpreter imports (the current PYTHONPATH), B the one in OTHER (put first\n"
            "on PYTHONPATH). Every run is a fresh subprocess; a pair is a run of A and a run of\n"
            "B back to back, in the order A,B then B,A alternately, so that the machine's\n"
            "drift (±30 % within minutes on a shared VM) falls on both alike. Printed per case:\n"
            "the median UAV-steps/s of A and of B, and min / median / max of the per-pair\n"
            "ratio B/A (above 1: B is faster). Trust the ratios, not the two medians: the\n"
            "medians still carry the drift. The autoreset-* cases time the steps in which\n"
            "every sub-environment resets, as UAV-steps/s. The usarsim.__file__ that A and B\n"
            "imported is printed, to show they are different builds.\n\n"
            "example:\n"
            "  PYTHONPATH=/tmp/pkg python steps_per_second.py 3 --compare /tmp/pkg_old \\\n"
            "      --pairs 5 --cases state-1024,full-1024"),
    )
    parser.add_argument("seconds", nargs="?", type=_positive_float, default=3.0,
                        help="seconds per case (per run with --compare; default 3)")
    parser.add_argument("--compare", metavar="OTHER",
                        help="another build of the package: a directory holding usarsim/ (with its "
                             "_core.abi3.so), or a .whl")
    parser.add_argument("--pairs", type=_positive_int, default=None,
                        help="with --compare: A/B pairs per case (default 5)")
    parser.add_argument("--cases", type=_case_list, default=None,
                        help="with --compare: comma-separated cases (default %s); all: %s"
                             % (",".join(DEFAULT_CASES), ", ".join(CASES)))
    parser.add_argument("--child", choices=list(CASES), help=argparse.SUPPRESS)
    args = parser.parse_args(argv)

    if args.child:
        run_child(args.child, args.seconds)
        return
    if args.compare is None:
        if args.pairs is not None or args.cases is not None:
            parser.error("--pairs and --cases apply only with --compare")
        run_default(args.seconds)
        return
    with tempfile.TemporaryDirectory(prefix="usarsim-compare-") as tmp:
        other = _resolve_other(parser, args.compare, tmp)
        run_compare(args.seconds, other, args.pairs or 5, args.cases or DEFAULT_CASES, shown_as=args.compare)


if __name__ == "__main__":
    main()
