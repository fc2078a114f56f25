"""Waiting: time without progress toward a task's workstation, from ground truth (pure).

One definition for every coordination mode (docs/reference/metrics.md, *waiting*): during each
completed task, from when it began until its robot reached the workstation, every whole simulated
second in which the robot came less than ``min_progress`` metres nearer to that workstation counts
as waiting. Nearer is measured along the free space of the world's map (the geodesic distance on
its free cells, 8-connected: :func:`geodesic_field`), so a robot driving round an obstacle makes
progress and one parked at a waiting spot, held in a queue or backing off does not. Positions
come from the simulator (``track`` of its summary: every robot's ground-truth x, y at each whole
simulated second), not from the robots.

Tasks still open when the run ends, and the time between a task's end and the next one's start
(a robot with nothing to do), are not counted.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np

MIN_PROGRESS_M = 0.05
"""[m] per simulated second: less than this nearer to the workstation is no progress (a fifth of
the waffle's cruising speed, well above the centimetre of the track's rounding)."""


def geodesic_field(free: np.ndarray, resolution: float, goal_rc: tuple[int, int]) -> np.ndarray:
    """Distance [m] from every free cell to ``goal_rc`` through free cells (8-connected, the
    diagonal step resolution x sqrt 2); ``inf`` where unreachable or not free.

    Args:
        free: (H, W) bool, True where a robot may stand (the map's free cells).
        resolution: [m] per cell.
        goal_rc: (row, column) of the goal; the free cell nearest it is used if it is not free.

    Source: Dijkstra's shortest paths on the grid graph (``scipy.sparse.csgraph.dijkstra``).
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import dijkstra

    h, w = free.shape
    index = np.full(free.shape, -1, dtype=np.int64)
    cells = np.flatnonzero(free.ravel())
    index.ravel()[cells] = np.arange(len(cells))
    rows, cols, weights = [], [], []
    for dr, dc, cost in ((0, 1, 1.0), (1, 0, 1.0), (1, 1, math.sqrt(2)), (1, -1, math.sqrt(2))):
        a = index[0:h - dr, max(0, -dc):w - max(0, dc)]  # (r, c) ...
        b = index[dr:h, max(0, dc):w - max(0, -dc)]  # ... and (r + dr, c + dc)
        ok = (a >= 0) & (b >= 0)
        rows.append(a[ok])
        cols.append(b[ok])
        weights.append(np.full(int(ok.sum()), cost * resolution))
    n = len(cells)
    graph = coo_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))),
                       shape=(n, n)).tocsr()
    r, c = goal_rc
    if not (0 <= r < h and 0 <= c < w and free[r, c]):
        rr, cc = np.nonzero(free)
        k = int(np.argmin((rr - r) ** 2 + (cc - c) ** 2))
        r, c = int(rr[k]), int(cc[k])
    dist = dijkstra(graph, directed=False, indices=int(index[r, c]))
    out = np.full(free.shape, np.inf)
    out.ravel()[cells] = dist
    return out


class DistanceField:
    """Geodesic distance [m] from points to targets on one map, a field per target cell, made
    when first asked (:func:`geodesic_field`).

    Args:
        occupancy: (H, W) int8 occupancy (0 free, 100 occupied, -1 unknown; row 0 at
            ``origin`` y), as :class:`swarm_scene.occupancy.OccupancyMap` ``data``.
        resolution: [m] per cell.
        origin: (2,) x, y [m] of cell (0, 0)'s lower-left corner in ``map``.
    """

    def __init__(self, occupancy: np.ndarray, resolution: float, origin):
        self.free = np.asarray(occupancy) == 0
        self.resolution = float(resolution)
        self.origin = np.asarray(origin, dtype=float)[:2]
        self._fields: dict[tuple[int, int], np.ndarray] = {}

    def _rc(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        rc = np.floor((np.asarray(xy, dtype=float) - self.origin) / self.resolution).astype(int)
        h, w = self.free.shape
        return np.clip(rc[..., 1], 0, h - 1), np.clip(rc[..., 0], 0, w - 1)

    def __call__(self, target, xy: np.ndarray) -> np.ndarray:
        """(K,) geodesic distances [m] from the points ``xy`` (K, 2) to ``target`` (x, y) [m]
        (the straight line where the map leaves a point unreachable)."""
        goal = np.asarray(target, dtype=float)[:2]
        r0, c0 = (int(v) for v in self._rc(goal))
        if (r0, c0) not in self._fields:
            self._fields[(r0, c0)] = geodesic_field(self.free, self.resolution, (r0, c0))
        xy = np.asarray(xy, dtype=float).reshape(-1, 2)
        r, c = self._rc(xy)
        d = self._fields[(r0, c0)][r, c]
        return np.where(np.isfinite(d), d, np.hypot(*(xy - goal).T))


def waiting_s(track: Sequence[Sequence[float]],
              tasks: Sequence[tuple[float, float, tuple[float, float]]],
              distance: Callable[[tuple[float, float], np.ndarray], np.ndarray],
              period_s: float = 1.0, min_progress: float = MIN_PROGRESS_M) -> float:
    """[s] simulated one robot waited during its completed tasks (the module doc).

    Args:
        track: [k] the robot's x, y [m] at simulated time (k + 1) x ``period_s``.
        tasks: (start [s], end [s], (x, y) [m] of its workstation) of each completed task.
        distance: ``distance(target, xy (K, 2))`` -> (K,) [m] (:class:`DistanceField`).
        period_s: [s] between two samples of ``track``.
        min_progress: [m] per ``period_s``: less progress is waiting.
    """
    pts = np.asarray(track, dtype=float).reshape(-1, 2)
    if len(pts) < 2:
        return 0.0
    times = (np.arange(len(pts)) + 1) * period_s
    total = 0.0
    for start, end, target in tasks:
        k = np.flatnonzero((times >= start - 1e-9) & (times <= end + 1e-9))
        if len(k) < 2:
            continue
        d = distance(target, pts[k])
        total += float(np.sum(d[:-1] - d[1:] < min_progress)) * period_s
    return total
