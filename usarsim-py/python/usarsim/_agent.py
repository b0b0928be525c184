"""Python agents flown by ucc-client's runner (missions, iterations, logs, pictures)."""

from __future__ import annotations

from ._core import Command, State, fly as _fly


class Agent:
    """Base class of a Python control algorithm.

    Subclass it and implement :meth:`step`; :func:`usarsim.fly` creates one instance per
    iteration (calling the class with no arguments) and calls ``step`` whenever new sensor
    data has arrived. A GotoXyz mission counts as done within ``reached`` metres of its
    target (or when ``step`` returns ``Command(done=True)``); a Hover mission after its
    seconds.
    """

    def step(self, state: State) -> Command:
        """Return the speed command for this moment (see :class:`usarsim.Command`)."""
        raise NotImplementedError("usarsim.Agent subclasses implement step(state) -> usarsim.Command")


def fly(agent_class, missions, **options) -> dict:
    """Flies `agent_class` through `missions` with ucc-client's runner.

    ``missions``: a list of ``(x, y, z)`` targets (GotoXyz) and ``{"hover": seconds}``.
    Options: ``server`` (``"host:port"``; default: a usar-server started in this process, in
    lockstep, at full speed), ``start`` (x, y, z), ``iterations``, ``log_dir`` (logs,
    trajectories CSV, map pictures SVG/PNG, results table), ``map`` (for the local server and
    the pictures), ``robot``, ``reached``, ``mission_timeout`` (simulated s), ``lockstep``,
    ``quiet``. Returns a dict: ``iterations`` (status, missions_done, duration, distance,
    trajectory, files per iteration), ``completed``, ``failed``, ``overlay``, ``results``.
    An exception raised by the agent ends the run and is raised here.
    """
    if not (isinstance(agent_class, type) and issubclass(agent_class, Agent)):
        raise ValueError(f"agent_class: expected a subclass of usarsim.Agent, got {agent_class!r}")
    return _fly(agent_class, list(missions), **options)
