"""usarsim side by side with gym-pybullet-drones and PyFlyt, in one run on one machine.

    python usarsim-py/benchmarks/peers.py                  # 3 runs of 5 s per case
    python usarsim-py/benchmarks/peers.py --runs 1 --seconds 2 --only usarsim

Install what you want compared (a simulator that does not import is skipped, with a line
saying how to install it):

    pip install ./usarsim-py        # or a built wheel: pip install usarsim-*.whl
    pip install PyFlyt              # from PyPI (pulls pybullet)
    pip install git+https://github.com/utiasDSL/gym-pybullet-drones   # not on PyPI
    # (that pulls stable-baselines3 and torch; the envs need only, with --no-deps:
    #  pip install pillow transforms3d scipy "setuptools<82")

Every case steps with random actions drawn uniformly from the env's own action space (so a
"random action" means different things: ±5 % around hover RPM for gym-pybullet-drones,
random body rates and thrust for PyFlyt and usarsim's "rates" mode, random velocity
set-points for usarsim's default stsAirRobot); episodes end and reset as they come (the
count is printed: resets are part of the cost). A UAV-step is one UAV advanced one control
period of its env; the periods differ (usarsim 0.1 s by default, gym-pybullet-drones 1/30 s,
PyFlyt 1/40 s), so the fair figure is **simulated UAV-seconds per wall second** (UAV-steps/s
× period, summed over the UAVs), printed beside UAV-steps/s, with the physics rate each uses.
The like-for-like usarsim cases fly the rigid-body Crazyflie on body rates at 1/40 s,
state-only; the stsAirRobot cases are usarsim's default kinematic model (velocities imposed),
not comparable in physics.

Per CPU-second is the CPU time of the process and, for Gymnasium's AsyncVectorEnv, of its
worker processes (user + system, all threads): on a shared machine it is steadier than the
wall clock, which depends on the free cores (usarsim's vector env uses every core; a pybullet
world one, the AsyncVectorEnv cases one per worker), though contention moves it too.

Published, not run here: QuadSwarm (Huang et al. 2023, arXiv:2306.09537) reports over 48,500
samples/s with one quadrotor (over 62,000 with eight) on a 16-core CPU.
"""

import argparse
import contextlib
import ctypes
import importlib.metadata
import os
import platform
import statistics
import sys
import time
import warnings

import numpy as np

warnings.filterwarnings("ignore")  # the peers' deprecation and env-checker warnings, once per env

LIBC = ctypes.CDLL(None)

INSTALL = {
    "usarsim": "pip install ./usarsim-py",
    "gym-pybullet-drones": "pip install git+https://github.com/utiasDSL/gym-pybullet-drones",
    "PyFlyt": "pip install PyFlyt",
}


@contextlib.contextmanager
def quiet():
    """Silence fds 1 and 2 (pybullet's C code and the peers print on every world they build);
    an exception still propagates and is reported once the fds are back."""
    sys.stdout.flush()
    sys.stderr.flush()
    LIBC.fflush(None)  # C's stdio buffers too, when stdout is a pipe
    saved, null = [os.dup(1), os.dup(2)], os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    try:
        yield
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        LIBC.fflush(None)
        for fd, copy in ((1, saved[0]), (2, saved[1])):
            os.dup2(copy, fd)
            os.close(copy)
        os.close(null)


def version(dist):
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "unknown (not installed as a distribution)"


def cpu_seconds(pids=()):
    """This process's CPU time (all threads) plus that of the worker processes `pids`."""
    total = time.process_time()
    tick = os.sysconf("SC_CLK_TCK")
    for pid in pids:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
        total += (int(fields[11]) + int(fields[12])) / tick  # utime, stime (fields 14, 15)
    return total


class Case:
    """One configuration. `make()` builds it and returns (step, close, pids, period, physics
    Hz): `step()` advances every UAV one control period and returns (episodes ended, UAV-steps
    taken, wall seconds spent in resets it called, or None where resets run inside the
    env's step and cannot be told apart); `pids` are worker processes whose CPU time counts too; `period` is the simulated
    seconds of one step, read from the built env where the env says it."""

    def __init__(self, sim, name, make):
        self.sim, self.name, self.make = sim, name, make
        self.period = self.physics_hz = None

    def time(self, seconds):
        with quiet():
            step, close, pids, self.period, self.physics_hz = self.make()
            for _ in range(3):  # warm-up: first steps fill caches
                step()
        try:
            n = ended = resetting = 0
            w0, c0 = time.perf_counter(), cpu_seconds(pids)
            while time.perf_counter() - w0 < seconds or n == 0:
                e, k, r = step()
                ended += e
                n += k
                resetting = None if r is None or resetting is None else resetting + r
            w1, c1 = time.perf_counter(), cpu_seconds(pids)
        finally:
            with quiet():
                close()
        stepping = None if resetting is None else n / max(w1 - w0 - resetting, 1e-9)
        return n / (w1 - w0), n / max(c1 - c0, 1e-9), 1000.0 * ended / n, stepping


# --- stepping loops shared by the cases -------------------------------------------------------

def single(make_env):
    """One Gymnasium env, reset when an episode ends (quietly: the peers print on reset)."""
    env = make_env()
    with quiet():
        env.reset(seed=0)
    space = env.action_space
    space.seed(0)

    def step():
        _, _, term, trunc, _ = env.step(space.sample())
        if term or trunc:
            return 1, 1, timed_reset(env.reset)
        return 0, 1, 0.0

    return env, step


def timed_reset(reset):
    """Reset quietly; the wall seconds it took."""
    t = time.perf_counter()
    with quiet():
        reset()
    return time.perf_counter() - t


def gym_async(env_id, workers=2, **kwargs):
    """Gymnasium's AsyncVectorEnv over `workers` processes (its autoreset, NEXT_STEP)."""
    import gymnasium

    class Quiet(gymnasium.Wrapper):  # the workers' resets print too
        def reset(self, **kw):
            with quiet():
                return self.env.reset(**kw)

    venv = gymnasium.vector.AsyncVectorEnv([lambda: Quiet(gymnasium.make(env_id, **kwargs))] * workers)
    venv.reset(seed=0)
    space = venv.action_space
    space.seed(0)

    def step():
        _, _, term, trunc, _ = venv.step(space.sample())
        return int(np.count_nonzero(term | trunc)), workers, None

    return venv, step, [p.pid for p in venv.processes]


def grid(n, spacing, z):
    """`n` start positions on a square grid `spacing` apart, centred on the origin, at `z`."""
    side = int(np.ceil(np.sqrt(n)))
    xy = (np.stack(np.divmod(np.arange(n), side), 1) - (side - 1) / 2) * spacing
    return np.column_stack([xy, np.full(n, z)])


# --- usarsim ------------------------------------------------------------------------------------

PHYSICS_HZ = 200  # usarsim's physics tick is 5 ms (docs/python.md, the `period` option)
QUAD_HZ = "200 (400: 2 substeps)"  # the quadrotor model integrates twice per tick (docs/quadrotor.md)


def usarsim_cases(drones):
    import gymnasium
    import usarsim  # noqa: F401  (registers usarsim/*)

    def rate(options):
        return QUAD_HZ if options.get("robot") in ("Crazyflie", "stsQuadrotor") else PHYSICS_HZ

    def one(env_id, **options):
        def make():
            env, step = single(lambda: gymnasium.make(env_id, **options))
            return step, env.close, (), options.get("period", 0.1), rate(options)

        return make

    def vector(num, task, **options):
        def make():
            venv = usarsim.vector_env(num, task, **options)
            venv.reset(seed=0)
            # Fresh actions every step, as the other cases sample them (repeating a few fixed
            # ones flew every UAV into a wall: steps_per_second.py's "pressed" case).
            space = venv.action_space
            space.seed(0)

            def step():
                _, _, term, trunc, _ = venv.step(space.sample())
                return int(np.count_nonzero(term | trunc)), num, None

            return step, venv.close, (), options.get("period", 0.1), rate(options)

        return make

    state = dict(state_only=True, flat=True)
    # The rigid-body quadrotor (the Crazyflie 2.x preset, as gym-pybullet-drones' cf2x) on
    # body rates + collective thrust (PyFlyt's default action) at 40 Hz (PyFlyt's agent rate).
    quad = dict(robot="Crazyflie", action_mode="rates", period=0.025, **state)
    cases = [Case("usarsim", "1 UAV, gymnasium.make Waypoints-v0, stsAirRobot, full obs",
                  one("usarsim/Waypoints-v0"))]
    for n in (256, 1024):
        cases.append(Case("usarsim", f"vector env {n}, stsAirRobot, full obs", vector(n, "waypoints")))
        cases.append(Case("usarsim", f"vector env {n}, stsAirRobot, state-only", vector(n, "waypoints", **state)))
    cases.append(Case("usarsim", "1 UAV, gymnasium.make Hover-v0, Crazyflie rates, state",
                      one("usarsim/Hover-v0", **quad)))
    for n in sorted({drones, 1024}):
        cases.append(Case("usarsim", f"vector env {n}, Crazyflie rates, state-only", vector(n, "hover", **quad)))
    return cases


# --- the peers: one drone, N drones in one pybullet world, a 2-process AsyncVectorEnv -----------

def gpd_cases(drones):
    import gymnasium

    with quiet():
        import gym_pybullet_drones  # noqa: F401  (registers hover-aviary-v0)
        from gym_pybullet_drones.envs import MultiHoverAviary

    def rates(env):  # control period and physics rate as the built env has them
        u = env.unwrapped
        return 1.0 / u.CTRL_FREQ, u.PYB_FREQ

    def one():
        env, step = single(lambda: gymnasium.make("hover-aviary-v0"))
        return (step, env.close, ()) + rates(env)

    def multi():
        # A grid up to 0.25 m apart inside MultiHoverAviary's ±2 m box: its default start line
        # puts the 13th drone on past x = 2 m, which truncates every episode at its first step.
        spacing = min(0.25, 3.6 / np.ceil(np.sqrt(drones)))
        env = MultiHoverAviary(num_drones=drones, initial_xyzs=grid(drones, spacing, 0.5))
        env, step = single(lambda: env)

        def all_drones():
            ended, _, resetting = step()
            return ended, drones, resetting

        return (all_drones, env.close, ()) + rates(env)

    def two():
        venv, step, pids = gym_async("hover-aviary-v0")
        ctrl_hz, pyb_hz = venv.get_attr("CTRL_FREQ")[0], venv.get_attr("PYB_FREQ")[0]
        return step, venv.close, pids, 1.0 / ctrl_hz, pyb_hz

    return [
        Case("gym-pybullet-drones", "1 drone, HoverAviary (cf2x), RPM, kin obs", one),
        Case("gym-pybullet-drones", f"MultiHoverAviary, {drones} drones in one world", multi),
        Case("gym-pybullet-drones", "AsyncVectorEnv, 2 x HoverAviary", two),
    ]


def pyflyt_cases(drones):
    import gymnasium

    with quiet():
        import PyFlyt.gym_envs  # noqa: F401  (registers PyFlyt/*)
        from PyFlyt.pz_envs import MAQuadXHoverEnvV2
    env_id = max(k for k in gymnasium.registry if k.startswith("PyFlyt/QuadX-Hover-v"))
    short = env_id.split("/")[1]

    def rates(aviary, ratio):  # one env step: `ratio` aviary steps of updates_per_step physics steps
        return ratio * aviary.updates_per_step / aviary.physics_hz, aviary.physics_hz

    def one():
        env, step = single(lambda: gymnasium.make(env_id))
        return (step, env.close, ()) + rates(env.unwrapped.env, env.unwrapped.env_step_ratio)

    def multi():
        env = MAQuadXHoverEnvV2(start_pos=grid(drones, 0.5, 1.0), start_orn=np.zeros((drones, 3)))
        with quiet():
            env.reset(seed=0)
        for i, a in enumerate(env.possible_agents):
            env.action_space(a).seed(i)

        def step():  # counts the agents still in the episode (PyFlyt flies the ended ones on)
            resetting = timed_reset(env.reset) if not env.agents else 0.0  # all ended: a new episode
            actions = {a: env.action_space(a).sample() for a in env.agents}
            _, _, term, trunc, _ = env.step(actions)
            return sum(bool(term[a] or trunc[a]) for a in actions), len(actions), resetting

        return (step, env.close, ()) + rates(env.aviary, env.env_step_ratio)

    def two():
        probe = gymnasium.make(env_id).unwrapped  # the workers' Aviary does not travel by pipe
        probe.reset(seed=0)
        period_hz = rates(probe.env, probe.env_step_ratio)
        probe.close()
        venv, step, pids = gym_async(env_id)
        return (step, venv.close, pids) + period_hz

    return [
        Case("PyFlyt", f"1 drone, {short}, rates+thrust", one),
        Case("PyFlyt", f"MAQuadXHover, {drones} drones in one world (PettingZoo)", multi),
        Case("PyFlyt", f"AsyncVectorEnv, 2 x {short}", two),
    ]


SIMS = {"usarsim": ("usarsim", usarsim_cases), "gpd": ("gym-pybullet-drones", gpd_cases),
        "pyflyt": ("PyFlyt", pyflyt_cases)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter,
                                     epilog="QuadSwarm (arXiv:2306.09537) publishes over 48,500 samples/s "
                                            "on a 16-core CPU; it is cited, not run.")
    parser.add_argument("--seconds", type=float, default=5.0, help="timed seconds per case and run (default 5)")
    parser.add_argument("--runs", type=int, default=3, help="runs of every case; min/median/max over them (default 3)")
    parser.add_argument("--drones", type=int, default=64,
                        help="drones in the peers' one-world multi-drone cases, and usarsim's matching vector env "
                             "(default 64)")
    parser.add_argument("--only", default="usarsim,gpd,pyflyt",
                        help="comma-separated simulators to run: usarsim, gpd, pyflyt (default: all)")
    args = parser.parse_args()
    if args.seconds <= 0 or args.runs < 1 or args.drones < 1:
        parser.error("--seconds must be > 0, --runs and --drones >= 1")
    wanted = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = [s for s in wanted if s not in SIMS]
    if unknown:
        parser.error(f"--only: unknown simulator(s) {', '.join(unknown)}; choose from {', '.join(SIMS)}")

    cpu = next((line.split(":", 1)[1].strip() for line in open("/proc/cpuinfo") if line.startswith("model name")),
               platform.processor())
    print(f"machine: {os.cpu_count()} cores, {cpu}; Python {platform.python_version()}; "
          f"load average {os.getloadavg()[0]:.2f} at the start")
    print("versions: " + ", ".join(f"{d} {version(d)}" for d in
                                   ("usarsim", "gym-pybullet-drones", "PyFlyt", "pybullet", "gymnasium",
                                    "pettingzoo", "numpy")))
    cases = []
    for key in wanted:
        dist, build = SIMS[key]
        try:
            cases += build(args.drones)
        except ImportError as e:
            print(f"{dist}: not installed ({INSTALL[dist]}) [{e}]")
        except Exception as e:  # installed, but not as this script expects it
            print(f"{dist}: skipped, setting up failed: {type(e).__name__}: {e}")
    results = {id(c): [] for c in cases}
    for run in range(1, args.runs + 1):
        print(f"run {run} of {args.runs} (load average {os.getloadavg()[0]:.2f})")
        for c in cases:  # run-major: each run sees every case under the same load
            try:
                wall, per_cpu, ends, stepping = c.time(args.seconds)
            except Exception as e:  # a peer's API changed: say so, keep going
                print(f"  {c.sim}: {c.name}: failed: {type(e).__name__}: {e}")
                continue
            results[id(c)].append((wall, per_cpu, ends, stepping))
            print(f"  {c.sim:20s} {c.name:55s} {wall:10.0f} UAV-steps/s {per_cpu:10.0f} per CPU-s "
                  f"{wall * c.period:9.1f} simulated UAV-s/wall-s")
    print(f"load average at the end: {' '.join(f'{x:.2f}' for x in os.getloadavg())}")
    print(f"\nmin / median / max of {args.runs} run(s), {args.seconds:g} s each. Simulated UAV-seconds = "
          "UAV-steps x period (summed over the UAVs). The last column takes the wall time of the resets\n"
          "the loop called out (- where resets run inside the env's step).\n")
    print("| simulator | case | period (s) | physics (Hz) | UAV-steps/s (wall) | UAV-steps per CPU-s "
          "| simulated UAV-s per wall-s | simulated UAV-s per CPU-s | episodes ended per 1000 UAV-steps | UAV-steps/s without resets |")
    print("|---|---|---|---|---|---|---|---|---|---|")

    def mmm(xs, scale=1.0):
        xs = sorted(x * scale for x in xs)
        fmt = (lambda x: f"{x:,.0f}") if xs[-1] >= 100 else (lambda x: f"{x:.1f}")
        return " / ".join(fmt(x) for x in (xs[0], statistics.median(xs), xs[-1]))

    for c in cases:
        r = results[id(c)]
        if not r:
            print(f"| {c.sim} | {c.name} | | | failed | | | | | |")
            continue
        wall, per_cpu, ends, stepping = zip(*r)
        stepping = "-" if None in stepping else mmm(stepping)
        print(f"| {c.sim} | {c.name} | {c.period:.4g} | {c.physics_hz} | {mmm(wall)} | {mmm(per_cpu)} "
              f"| {mmm(wall, c.period)} | {mmm(per_cpu, c.period)} | {statistics.median(ends):.0f} | {stepping} |")
    print("\nQuadSwarm (Huang et al. 2023, arXiv:2306.09537), published, not run here: over 48,500 samples/s "
          "with one quadrotor, over 62,000 with eight, on a 16-core CPU.")


if __name__ == "__main__":
    main()
