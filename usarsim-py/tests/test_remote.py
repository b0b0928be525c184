"""The remote environment's driver against servers that misbehave."""
import socket
import subprocess
import sys
import threading

FLOOD = 256 * 1024 * 1024


def _flooding_server():
    """A server that sends 256 MiB without a line ending, then hangs up."""
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(1)

    def drain(conn):
        try:
            while conn.recv(4096):
                pass
        except OSError:
            pass

    def serve():
        conn, _ = listener.accept()
        # What the client sends is read, so that the hang-up is a clean end of the stream.
        threading.Thread(target=drain, args=(conn,), daemon=True).start()
        chunk = b"x" * (1024 * 1024)
        try:
            for _ in range(FLOOD // len(chunk)):
                conn.sendall(chunk)
        except OSError:
            pass
        conn.shutdown(socket.SHUT_WR)
        listener.close()

    threading.Thread(target=serve, daemon=True).start()
    return "127.0.0.1:%d" % listener.getsockname()[1]


def test_an_endless_line_is_read_in_bounded_memory():
    """The defect: the remote driver read a line with an unbounded read_line, so a server
    (or anything listening on the port) that never ends its line made it buffer all of it."""
    addr = _flooding_server()
    script = (
        "import resource, usarsim._core as c\n"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss\n"
        "try:\n"
        "    c.Remote(%r, 'stsAirRobot', [0.0, 0.0, -1.0, 0.0])\n"
        "    print('connected')\n"
        "except ValueError as e:\n"
        "    print(e)\n"
        "print((resource.getrusage(resource.RUSAGE_SELF).ru_maxrss - before) // 1024)\n" % addr
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    message, grown_mib = out.stdout.strip().splitlines()
    assert message == f"server {addr}: the server closed the connection"
    assert int(grown_mib) < 64, f"the driver's memory grew by {grown_mib} MiB reading one line"


def test_a_remote_quadrotor_flown_into_a_wall_crashes_and_the_episode_ends(server):
    """A crash is the task's to judge: the remote env reports it as the in-process one does
    (the flight core must not turn it into an error)."""
    import gymnasium
    import numpy as np

    import usarsim  # noqa: F401  (registers the environments)

    env = gymnasium.make("usarsim/Waypoints-v0", robot="stsQuadrotor", start=(7, 0, -1, 0),
                         waypoints=[[-5, 0, -1]], max_steps=1000, server=server)
    env.reset(seed=0)
    for _ in range(200):
        obs, reward, term, trunc, info = env.step(np.array([1, 0, 0, 0], np.float32))
        if term:
            break
    assert term and not trunc, "the crash ends the episode"
    assert bool(info["crashed"])
    assert reward < -50  # the crash penalty
    assert obs["position"][0] < 10.0  # stopped at the wall
    env.close()


def test_a_remote_env_with_a_period_shorter_than_the_sensors_interval_starts(server):
    """Periods of 0.05 and 0.02 s end before the first Position reading (0.1 s after the
    spawn): the env hovers until it has read, as the in-process world does, instead of
    saying the robot did not spawn."""
    import numpy as np

    import usarsim

    for period in (0.05, 0.02):
        env = usarsim.UsarsimEnv(server=server, period=period, start=(2, 1, -1, 0))
        obs, _ = env.reset(seed=0)
        assert np.allclose(obs["position"], [2, 1, -1], atol=0.05), (period, obs["position"])
        for _ in range(10):
            obs, *_ = env.step(np.array([1, 0, 0, 0], np.float32))
        assert obs["position"][0] > 2.05, f"period {period}: it flew forward ({obs['position']})"
        env.close()
