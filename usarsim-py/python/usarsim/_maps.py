"""Map geometry helpers: free-space sampling for starts and waypoints."""

from __future__ import annotations

import numpy as np

from ._core import stream_sample

#: Heights (z, metres, z down) where random starts and waypoints are placed.
FLIGHT_BAND = (-3.0, -1.0)


class MapInfo:
    """The map seen from above, as the Rust core reports it (convex outlines and heights)."""

    def __init__(self, batch) -> None:
        self.starts = batch.start_poses()
        self.shapes = [(np.asarray(o, dtype=np.float64), zmin, zmax) for o, zmin, zmax in batch.top_view()]
        pts = np.concatenate([s[0] for s in self.shapes]) if self.shapes else np.zeros((1, 2))
        for _, x, y, _, _ in self.starts:
            pts = np.vstack([pts, [x, y]])
        self.lo = pts.min(axis=0)
        self.hi = pts.max(axis=0)
        #: The bottom of the lowest solid (z down): below it is outside the map.
        self.z_bottom = max((zmax for _, _, zmax in self.shapes), default=np.inf)
        # Solids that reach into the flight band (walls, buildings; not floor or ceiling).
        self.obstacles = [
            (o, o.min(axis=0), o.max(axis=0))
            for o, zmin, zmax in self.shapes
            if zmin < FLIGHT_BAND[1] + 0.5 and zmax > FLIGHT_BAND[0] - 0.5
        ]
        #: Their bounding boxes seen from above, (k, 2) corners each.
        self._box_lo = np.array([lo for _, lo, _ in self.obstacles]).reshape(-1, 2)
        self._box_hi = np.array([hi for _, _, hi in self.obstacles]).reshape(-1, 2)
        self._boxes = {}  # boxes(clearance), kept

    def start(self, key: str):
        """The PlayerStart with tag `key` as (x, y, z, yaw)."""
        for tag, x, y, z, yaw in self.starts:
            if tag.lower() == key.lower():
                return np.array([x, y, z, yaw])
        names = ", ".join(s[0] for s in self.starts) or "none"
        raise ValueError(f"start: no PlayerStart {key!r} in this map (known: {names})")

    def check_inside(self, p, what: str) -> None:
        """ValueError naming `what` unless (x, y, z) is within the map's extent and above its
        lowest solid."""
        x, y, z = (float(v) for v in p[:3])
        if not (self.lo[0] <= x <= self.hi[0] and self.lo[1] <= y <= self.hi[1]):
            raise ValueError(f"{what}: ({x:g}, {y:g}, {z:g}) is outside the map (x in {self.lo[0]:g}..{self.hi[0]:g}, "
                             f"y in {self.lo[1]:g}..{self.hi[1]:g})")
        if z >= self.z_bottom:
            raise ValueError(f"{what}: ({x:g}, {y:g}, {z:g}) is below the floor (z is down; the map's lowest solid "
                             f"ends at z = {self.z_bottom:g})")

    def is_free(self, p, clearance: float) -> bool:
        """Whether (x, y) is at least `clearance` from the bounding box of every obstacle."""
        return bool(self.free(np.asarray(p)[None], clearance)[0])

    def free(self, points, clearance: float) -> np.ndarray:
        """:meth:`is_free` of each row (x, y[, z]) of `points`, as a boolean array."""
        p = np.asarray(points, dtype=np.float64)
        x, y = np.ascontiguousarray(p[:, 0]), np.ascontiguousarray(p[:, 1])
        free = np.ones(len(p), dtype=bool)
        inside = np.empty(len(p), dtype=bool)
        # Box after box on whole columns: a few boxes, many points (a reset of 1024 rows
        # took 2.7x as long with one (n, k) comparison per bound).
        for (x0, y0), (x1, y1) in zip((self._box_lo - clearance).tolist(), (self._box_hi + clearance).tolist()):
            np.greater(x, x0, out=inside)
            inside &= x < x1
            inside &= y > y0
            inside &= y < y1
            free &= ~inside
        return free

    def sample(self, rng: np.random.Generator, n: int, clearance: float = 1.0, spacing: float = 1.2, near=None, radius=None):
        """`n` free points (x, y, z) in the flight band, `spacing` apart; within `radius` of `near` if given."""
        lo = self.lo + clearance + 0.5
        hi = self.hi - clearance - 0.5
        out: list[np.ndarray] = []
        for _ in range(20000):
            if len(out) == n:
                break
            if near is not None and radius is not None:
                xy = near[:2] + rng.uniform(-radius, radius, size=2)
                xy = np.clip(xy, lo, hi)
            else:
                xy = rng.uniform(lo, hi)
            p = np.array([xy[0], xy[1], rng.uniform(*FLIGHT_BAND)])
            if self.is_free(p, clearance) and all(np.linalg.norm(p[:2] - q[:2]) >= spacing for q in out):
                out.append(p)
        if len(out) < n:
            raise ValueError(f"map: could not find {n} free places {spacing} m apart in the flight band")
        return np.array(out)

    def boxes(self, clearance: float) -> np.ndarray:
        """The obstacles' boxes seen from above grown by `clearance`, rows of x0, y0, x1, y1
        (what :meth:`free` tests against; kept per clearance: read only)."""
        if clearance not in self._boxes:
            boxes = np.hstack([self._box_lo - clearance, self._box_hi + clearance]).reshape(-1, 4)
            self._boxes[clearance] = np.ascontiguousarray(boxes)
            self._boxes[clearance].flags.writeable = False
        return self._boxes[clearance]

    def _sample_args(self, clearance: float):
        """`stream_sample`'s map arguments: the bounds, the flight band and :meth:`boxes`."""
        lo = self.lo + clearance + 0.5
        hi = self.hi - clearance - 0.5
        return lo.tolist(), hi.tolist(), list(FLIGHT_BAND), self.boxes(clearance)

    def sample_rows(self, streams, rows, n: int, clearance: float = 1.0, spacing: float = 1.2, near=None,
                    radius: float = 0.0) -> np.ndarray:
        """:meth:`sample` for each of `rows` from its own stream (`streams`, a
        ``_task.Streams``), shape (len(rows), n, 3), in Rust: each candidate takes three
        uniform draws of the row's stream (x, y, then z), as :meth:`_sample_rows_python`
        defines. `near`: one (x, y, ...) per row."""
        lo, hi, band, boxes = self._sample_args(clearance)
        near = None if near is None else np.ascontiguousarray(near, dtype=np.float64)
        return stream_sample(streams.keys, streams.drawn, np.asarray(rows, dtype=np.int64), n, lo, hi, band, boxes,
                             spacing, near, radius)

    def _sample_rows_python(self, streams, rows, n: int, clearance: float = 1.0, spacing: float = 1.2, near=None,
                            radius: float = 0.0) -> np.ndarray:
        """:meth:`sample_rows` in Python: the definition `stream_sample` must equal (tests)."""
        lo, hi, _, _ = self._sample_args(clearance)
        out = np.zeros((len(rows), n, 3))
        for m, r in enumerate(rows):
            found = 0
            for _ in range(20000):
                if found == n:
                    break
                u = streams.doubles([r], 3)[0]
                if near is not None:
                    xy = np.clip(np.asarray(near[m][:2]) + (-radius + (radius - -radius) * u[:2]), lo, hi)
                else:
                    xy = np.asarray(lo) + (np.asarray(hi) - np.asarray(lo)) * u[:2]
                p = np.array([xy[0], xy[1], FLIGHT_BAND[0] + (FLIGHT_BAND[1] - FLIGHT_BAND[0]) * u[2]])
                if self.is_free(p, clearance) and all(np.sqrt(np.sum((p[:2] - q[:2]) ** 2)) >= spacing
                                                      for q in out[m, :found]):
                    out[m, found] = p
                    found += 1
            if found < n:
                raise ValueError(f"map: could not find {n} free places {spacing} m apart in the flight band")
        return out
