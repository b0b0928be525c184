import os
import shutil
import socket
import subprocess
import time
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _server_binary() -> Path:
    """The usar-server binary: $USAR_SERVER, else built with cargo in the repository."""
    env = os.environ.get("USAR_SERVER")
    if env:
        return Path(env)
    if shutil.which("cargo") is None:
        pytest.skip("no cargo to build usar-server (set USAR_SERVER)")
    subprocess.run(["cargo", "build", "-q", "-p", "usar-server"], cwd=REPO, check=True)
    return REPO / "target" / "debug" / "usar-server"


@pytest.fixture(scope="session")
def server():
    """A usar-server on a free port (`host:port`), at maximum speed."""
    port = _free_port()
    proc = subprocess.Popen([str(_server_binary()), "--port", str(port), "--time-scale", "max", "--lockstep",
                             "--truth-port", "off", "--monitor-port", "off", "--wss-port", "off",
                             "--image-port", "off"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.time() + 30
    while time.time() < deadline:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=0.5).close()
            break
        except OSError:
            time.sleep(0.1)
    else:
        proc.kill()
        pytest.fail("usar-server did not start")
    yield f"127.0.0.1:{port}"
    proc.terminate()
    proc.wait(timeout=10)
