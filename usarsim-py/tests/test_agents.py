"""Python agents flown by ucc-client's runner, and the environment against a server over TCP."""

import subprocess

import gymnasium
import numpy as np
import pytest

import usarsim


class GoTo(usarsim.Agent):
    """Proportional controller towards the current target (heading stays north)."""

    def step(self, state):
        if state.target is None:
            return usarsim.Command(done=True)
        e = np.subtract(state.target, state.position)
        f, r, u = np.clip([e[0], e[1], -e[2]], -1, 1)
        return usarsim.Command(forward=f, right=r, up=u)


MISSIONS = [(2.0, 0.0, -1.5), (2.0, 2.0, -1.5), {"hover": 1.0}]


def test_python_agent_flies_a_mission_against_a_server_over_tcp(server, tmp_path):
    result = usarsim.fly(GoTo, MISSIONS, server=server, iterations=2, log_dir=str(tmp_path))
    assert result["completed"] == 2 and result["failed"] == 0
    it = result["iterations"][0]
    assert it["missions_done"] == 3
    last = it["trajectory"][-1]
    assert np.hypot(last[1] - 2.0, last[2] - 2.0) < 0.5
    names = {p.rsplit("/", 1)[-1].rsplit(".", 1)[-1] for p in map(str, it["files"])}
    assert {"csv", "svg", "png"} <= names
    # Lockstep: both iterations flew the same path.
    a, b = (np.array(i["trajectory"]) for i in result["iterations"])
    assert a.shape == b.shape and np.allclose(a[:, 1:], b[:, 1:])


def test_python_agent_with_a_server_in_the_process():
    result = usarsim.fly(GoTo, [(1.0, 1.0, -1.0)])
    assert result["completed"] == 1


def test_agent_exception_reaches_the_caller():
    class Broken(usarsim.Agent):
        def step(self, state):
            raise RuntimeError("boom in my agent")

    with pytest.raises(RuntimeError, match="boom in my agent"):
        usarsim.fly(Broken, [(1.0, 0.0, -1.0)])


def test_agent_returning_the_wrong_type_is_a_value_error():
    class Wrong(usarsim.Agent):
        def step(self, state):
            return (1, 0, 0, 0)

    with pytest.raises(ValueError, match="must return usarsim.Command"):
        usarsim.fly(Wrong, [(1.0, 0.0, -1.0)])


def test_bad_missions_are_value_errors():
    with pytest.raises(ValueError, match=r"missions\[1\]"):
        usarsim.fly(GoTo, [(1.0, 0.0, -1.0), "north"])
    with pytest.raises(ValueError, match="subclass of usarsim.Agent"):
        usarsim.fly(object, [(1.0, 0.0, -1.0)])


def test_remote_env_in_lockstep_matches_the_in_process_world(server):
    actions = np.random.default_rng(5).uniform(-1, 1, (30, 4)).astype(np.float32)

    def run(**kw):
        env = gymnasium.make("usarsim/Waypoints-v0", start=(0, 0, -1, 0), waypoints=[[3, 3, -2]], **kw)
        obs, info = env.reset(seed=4)
        out = [obs["position"]]
        for a in actions:
            obs, *_ = env.step(a)
            out.append(obs["position"])
        env.close()
        return np.array(out), info

    local, _ = run()
    remote1, info = run(server=server)
    remote2, _ = run(server=server)
    assert info["lockstep"]
    np.testing.assert_array_equal(remote1, remote2)
    # The wire carries 4 decimals.
    np.testing.assert_allclose(remote1, local, atol=2e-3)


def test_the_remote_first_observation_is_as_complete_as_the_in_process_one(server):
    """The remote env hovered only until Position had read (0.1 s): its first observation
    had placeholder sonars (4 m, not the 5 m they read in the empty room)."""
    first = []
    for kw in ({}, {"server": server}):
        env = gymnasium.make("usarsim/Waypoints-v0", start=(0, 0, -1, 0), **kw)
        first.append(env.reset(seed=0)[0])
        env.close()
    local, remote = first
    for key in ("position", "velocity", "sonar", "laser"):
        np.testing.assert_allclose(remote[key], local[key], atol=2e-3, err_msg=key)


def test_remote_episodes_after_reset_repeat_exactly(server):
    """Each reset reconnects; the next robot must not spawn while the last is still there
    (its sensors would read on other ticks: the episode differed, under load)."""
    env = gymnasium.make("usarsim/Waypoints-v0", server=server, start=(0, 0, -1, 0))
    episodes = []
    for _ in range(20):
        env.reset(seed=0)
        episodes.append([env.step(np.array([1, 0, 0, 0], np.float32))[0]["position"] for _ in range(3)])
    env.close()
    for episode in episodes[1:]:
        np.testing.assert_array_equal(episode, episodes[0])


def test_closed_server_is_a_value_error(tmp_path):
    from conftest import _free_port, _server_binary
    import socket
    import time

    port = _free_port()
    proc = subprocess.Popen([str(_server_binary()), "--port", str(port), "--time-scale", "max", "--lockstep",
                             "--truth-port", "off", "--monitor-port", "off", "--wss-port", "off",
                             "--image-port", "off"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    for _ in range(100):
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            break
        except OSError:
            time.sleep(0.1)
    env = gymnasium.make("usarsim/Hover-v0", server=f"127.0.0.1:{port}")
    env.reset(seed=0)
    env.step(env.action_space.sample())
    proc.terminate()
    proc.wait(timeout=10)
    with pytest.raises(ValueError, match=f"server 127.0.0.1:{port}"):
        for _ in range(5):
            env.step(env.action_space.sample())
    with pytest.raises(ValueError, match="cannot connect"):
        env.reset(seed=0)


def test_remote_env_without_lockstep_runs_on_sensor_time():
    """A server that does not offer lockstep (like a real USARSim): the env still flies."""
    from conftest import _free_port, _server_binary
    import socket
    import time

    port = _free_port()
    proc = subprocess.Popen([str(_server_binary()), "--port", str(port),
                             "--truth-port", "off", "--monitor-port", "off", "--wss-port", "off",
                             "--image-port", "off"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        for _ in range(100):
            try:
                socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
                break
            except OSError:
                time.sleep(0.1)
        env = gymnasium.make("usarsim/Waypoints-v0", server=f"127.0.0.1:{port}", start=(0, 0, -1, 0))
        obs, info = env.reset(seed=0)
        assert not info["lockstep"]
        for _ in range(5):
            obs, *_ = env.step(np.array([1, 0, 0, 0], np.float32))
        assert obs["position"][0] > 0.3  # real time: ~0.5 s at 2 m/s, give or take a tick
        env.close()
    finally:
        proc.terminate()
        proc.wait(timeout=10)


def test_ctrl_c_during_a_run_raises_keyboard_interrupt():
    import os
    import signal

    calls = []

    class Interrupted(usarsim.Agent):
        def step(self, state):
            calls.append(state.time)
            if len(calls) == 3:
                os.kill(os.getpid(), signal.SIGINT)
            return usarsim.Command(forward=1.0)

    # Python keeps SIGINT ignored when it starts ignored, as in a background job of a
    # non-interactive shell (`bash .ci/run &`): Ctrl-C then never interrupts anything, and
    # this test ran three whole iterations. Python's own handler makes it what a terminal has.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        result = usarsim.fly(Interrupted, [(5.0, 0.0, -1.0)], iterations=3)
    except KeyboardInterrupt:
        pass
    else:
        rows = [(it["status"], it["error"], len(it["trajectory"])) for it in result["iterations"]]
        pytest.fail(f"no KeyboardInterrupt: {len(calls)} agent steps, iterations {rows}")
    finally:
        signal.signal(signal.SIGINT, previous)
    # The run stopped at the next step, not after three iterations of 25 steps or more.
    assert len(calls) == 3
