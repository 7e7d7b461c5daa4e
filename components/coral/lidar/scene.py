"""Indoor scenes for the synthetic LiDAR: rooms joined by corridors, with pillars, plus the path through them.

`build_scene(seed)` is a pure function of its arguments: the same seed always gives the same walls
and the same path, so a generated bag (and its ground truth) can be cached by its parameters.
The floor plan is carved into an occupancy grid (rooms and corridors are free rectangles); every
boundary between a free and an occupied cell becomes a wall segment, merged along grid lines, so
ray casting only has to intersect a few hundred 2D segments extruded between floor and ceiling.
Called by `coral.lidar.generating`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

CELL_M = 0.2


@dataclass(frozen=True)
class Scene:
    """Walls as 2D segments (x1, y1, x2, y2) extruded from z=0 to `height`, and the path waypoints."""

    segments: np.ndarray
    height: float
    path: np.ndarray  # (K, 2) smoothed polyline the sensor follows, metres
    free: np.ndarray  # occupancy grid, True where free
    origin: tuple[float, float]  # world position of grid cell (0, 0)'s corner


def _carve(free: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> None:
    i0, i1 = int(round(min(x0, x1) / CELL_M)), int(round(max(x0, x1) / CELL_M))
    j0, j1 = int(round(min(y0, y1) / CELL_M)), int(round(max(y0, y1) / CELL_M))
    free[i0:i1, j0:j1] = True


def _fill_disc(free: np.ndarray, cx: float, cy: float, radius: float) -> None:
    ii, jj = np.meshgrid(np.arange(free.shape[0]), np.arange(free.shape[1]), indexing="ij")
    centres_x, centres_y = (ii + 0.5) * CELL_M, (jj + 0.5) * CELL_M
    free[(centres_x - cx) ** 2 + (centres_y - cy) ** 2 <= radius**2] = False


def _fill_box(free: np.ndarray, cx: float, cy: float, half: float) -> None:
    _carve_block = (
        slice(int(round((cx - half) / CELL_M)), int(round((cx + half) / CELL_M))),
        slice(int(round((cy - half) / CELL_M)), int(round((cy + half) / CELL_M))),
    )
    free[_carve_block] = False


def _wall_segments(free: np.ndarray) -> np.ndarray:
    """Edges between free and occupied cells, merged into maximal straight runs along grid lines."""
    padded = np.pad(free, 1, constant_values=False)
    segments: list[tuple[float, float, float, float]] = []
    # Vertical edges at x = i (between cell i-1 and i), running along j.
    vertical = padded[1:, 1:-1] != padded[:-1, 1:-1]
    for i in range(vertical.shape[0]):
        for start, stop in _runs(vertical[i]):
            segments.append((i * CELL_M, start * CELL_M, i * CELL_M, stop * CELL_M))
    horizontal = padded[1:-1, 1:] != padded[1:-1, :-1]
    for j in range(horizontal.shape[1]):
        for start, stop in _runs(horizontal[:, j]):
            segments.append((start * CELL_M, j * CELL_M, stop * CELL_M, j * CELL_M))
    return np.asarray(segments, dtype=np.float64)


def _runs(flags: np.ndarray) -> list[tuple[int, int]]:
    edges = np.diff(np.concatenate([[0], flags.astype(np.int8), [0]]))
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _smooth(waypoints: np.ndarray, iterations: int = 4) -> np.ndarray:
    """Chaikin corner cutting: a smooth path that stays close to the corridor centre lines."""
    path = waypoints
    for _ in range(iterations):
        q = 0.75 * path[:-1] + 0.25 * path[1:]
        r = 0.25 * path[:-1] + 0.75 * path[1:]
        inner = np.empty((2 * len(q), 2))
        inner[0::2], inner[1::2] = q, r
        path = np.vstack([path[:1], inner, path[-1:]])
    return path


def _distance_to_path(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    a, b = path[:-1], path[1:]
    ab = b - a
    ap = points[:, None, :] - a[None, :, :]
    t = np.clip((ap * ab).sum(-1) / np.maximum((ab * ab).sum(-1), 1e-12), 0.0, 1.0)
    closest = a[None] + t[..., None] * ab[None]
    return np.linalg.norm(points[:, None, :] - closest, axis=-1).min(axis=1)


def build_scene(seed: int, rooms: int = 4, height: float = 3.0) -> Scene:
    """A chain of `rooms` rooms joined by L-shaped corridors, with pillars and boxes off the path."""
    rng = np.random.default_rng(seed)
    centres: list[tuple[float, float]] = []
    sizes: list[tuple[float, float]] = []
    x = 8.0
    for index in range(rooms):
        width, depth = rng.uniform(7.0, 11.0), rng.uniform(6.0, 10.0)
        y = 14.0 + (rng.uniform(-4.0, 4.0) if index else 0.0)
        centres.append((x, y))
        sizes.append((width, depth))
        x += width / 2 + rng.uniform(8.0, 12.0) + 5.5
    extent_x = x + 10.0
    free = np.zeros((int(extent_x / CELL_M), int(30.0 / CELL_M)), dtype=bool)
    for (cx, cy), (w, d) in zip(centres, sizes, strict=True):
        _carve(free, cx - w / 2, cy - d / 2, cx + w / 2, cy + d / 2)

    corridor = 2.4
    waypoints: list[tuple[float, float]] = [centres[0]]
    for (ax, ay), (bx, by) in zip(centres[:-1], centres[1:], strict=True):
        # Horizontal leg out of room a, then vertical into line with room b, then into b.
        mid_x = (ax + bx) / 2
        _carve(free, ax, ay - corridor / 2, mid_x + corridor / 2, ay + corridor / 2)
        _carve(
            free,
            mid_x - corridor / 2,
            min(ay, by) - corridor / 2,
            mid_x + corridor / 2,
            max(ay, by) + corridor / 2,
        )
        _carve(free, mid_x - corridor / 2, by - corridor / 2, bx, by + corridor / 2)
        waypoints += [(mid_x, ay), (mid_x, by), (bx, by)]
    path = _smooth(np.asarray(waypoints, dtype=np.float64))

    # Pillars and boxes give ICP something to hold on to beyond the flat walls of a room.
    for (cx, cy), (w, d) in zip(centres, sizes, strict=True):
        candidates = np.column_stack(
            [
                rng.uniform(cx - w / 2 + 1.0, cx + w / 2 - 1.0, 12),
                rng.uniform(cy - d / 2 + 1.0, cy + d / 2 - 1.0, 12),
            ]
        )
        clear = candidates[_distance_to_path(candidates, path) > 1.8][:4]
        for k, (px, py) in enumerate(clear):
            if k % 2 == 0:
                _fill_disc(free, px, py, rng.uniform(0.25, 0.45))
            else:
                _fill_box(free, px, py, rng.uniform(0.3, 0.6))
    return Scene(segments=_wall_segments(free), height=height, path=path, free=free, origin=(0.0, 0.0))
