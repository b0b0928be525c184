"""A top-view picture (numpy only): map solids in the flight band, UAVs, trails, laser rays."""

from __future__ import annotations

import numpy as np

from ._maps import MapInfo

COLORS = np.array([[31, 119, 180], [214, 39, 40], [44, 160, 44], [148, 103, 189], [255, 127, 14]], np.uint8)


def _fill_convex(img, xs, ys, poly, color) -> None:
    """Fills the convex polygon `poly` (pixel coordinates, col/row) into `img`."""
    c0, r0 = np.floor(poly.min(axis=0)).astype(int)
    c1, r1 = np.ceil(poly.max(axis=0)).astype(int)
    h, w = img.shape[:2]
    c0, r0, c1, r1 = max(c0, 0), max(r0, 0), min(c1, w - 1), min(r1, h - 1)
    if c0 > c1 or r0 > r1:
        return
    cc, rr = np.meshgrid(np.arange(c0, c1 + 1) + 0.5, np.arange(r0, r1 + 1) + 0.5)
    inside_pos = np.ones_like(cc, dtype=bool)
    inside_neg = np.ones_like(cc, dtype=bool)
    for (ax, ay), (bx, by) in zip(poly, np.roll(poly, -1, axis=0)):
        cross = (bx - ax) * (rr - ay) - (by - ay) * (cc - ax)
        inside_pos &= cross >= 0
        inside_neg &= cross <= 0
    img[r0:r1 + 1, c0:c1 + 1][inside_pos | inside_neg] = color


def _line(img, a, b, color) -> None:
    n = int(max(abs(b[0] - a[0]), abs(b[1] - a[1]), 1))
    t = np.linspace(0.0, 1.0, n + 1)
    cols = np.round(a[0] + (b[0] - a[0]) * t).astype(int)
    rows = np.round(a[1] + (b[1] - a[1]) * t).astype(int)
    ok = (rows >= 0) & (rows < img.shape[0]) & (cols >= 0) & (cols < img.shape[1])
    img[rows[ok], cols[ok]] = color


class TopView:
    """Draws frames of one map; x (north) points up, y (east) right."""

    def __init__(self, map_info: MapInfo, size: int = 400) -> None:
        self.map = map_info
        span = np.maximum(map_info.hi - map_info.lo, 1.0)
        # The longer side of the map is `size` pixels; the picture has the map's proportions.
        self.scale = (size - 1) / span.max()
        height, width = (int(s * self.scale + 1e-6) + 1 for s in span)
        self.size = (height, width)
        self.background = np.full((height, width, 3), 255, np.uint8)
        for poly, _, _ in map_info.obstacles:
            _fill_convex(self.background, None, None, self.px(poly), (90, 90, 90))

    def px(self, xy) -> np.ndarray:
        """Metres (x, y) to pixel (col, row)."""
        xy = np.atleast_2d(np.asarray(xy, dtype=np.float64))
        col = (xy[:, 1] - self.map.lo[1]) * self.scale
        row = (self.map.hi[0] - xy[:, 0]) * self.scale
        return np.column_stack([col, row])

    def draw(self, positions, yaws, lasers, trails, targets) -> np.ndarray:
        """One RGB frame (height, width, 3) uint8; the longer side is `size` pixels."""
        img = self.background.copy()
        fov, res = 4.189, 0.0184086914
        for i, (p, yaw) in enumerate(zip(positions, yaws)):
            color = COLORS[i % len(COLORS)]
            if lasers is not None:
                ranges = lasers[i]
                bearings = yaw + fov / 2 - np.arange(len(ranges)) * res
                for b, r in list(zip(bearings, ranges))[::8]:
                    end = p[:2] + r * np.array([np.cos(b), np.sin(b)])
                    _line(img, self.px(p[:2])[0], self.px(end)[0], (255, 200, 200))
            trail = trails[i] if trails is not None else []
            for a, b in zip(trail[:-1], trail[1:]):
                _line(img, self.px(a)[0], self.px(b)[0], color)
            for t in (targets[i] if targets is not None else []):
                c = self.px(t[:2])[0]
                _fill_convex(img, None, None, c + np.array([[-3, -3], [3, -3], [3, 3], [-3, 3]]), (0, 170, 0))
            c = self.px(p[:2])[0]
            _fill_convex(img, None, None, c + 5 * np.array([[np.cos(a), np.sin(a)] for a in np.linspace(0, 2 * np.pi, 12, endpoint=False)]), color)
            head = p[:2] + 0.6 * np.array([np.cos(yaw), np.sin(yaw)])
            _line(img, c, self.px(head)[0], (0, 0, 0))
        return img
