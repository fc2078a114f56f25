"""Compiled costmap geometry (:mod:`swarm_nav.costmap`), with numba.

:func:`segment_profile` cuts a segment at the grid lines it crosses, the arithmetic of the numpy
version it replaced operation for operation, so its lengths and costs are the same to the last bit
(``tests/swarm_nav/test_planner_equivalence.py``); the planner's shortcuts and the holding
pattern's line-of-sight checks call it for every candidate segment.  See
:mod:`swarm_nav.dwa_kernels` for the rules.  Compiled on first use and cached beside this file.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from swarm_nav.config import CostmapConfig

LETHAL = CostmapConfig.LETHAL_OBSTACLE


@njit(cache=True, nogil=True)
def segment_profile(costs, res, ox, oy, ax, ay, bx, by):
    """The cells a segment passes through: the length [m] in each and its cost
    (:func:`swarm_nav.costmap.segment_profile`'s arithmetic).

    Args:
        costs: (H, W) uint8 costmap; row 0 at ``y = oy``; res: cell size [m].
        ox, oy: x, y [m] of the grid's lower-left corner in ``map``.
        ax, ay, bx, by: x, y [m] of the segment's start and of its end.

    Returns:
        ``(lengths, cell_costs)``: (P,) length [m] of each piece, in order, and (P,) uint8 its
        cell's cost (``LETHAL`` off the map).
    """
    dx = bx - ax
    dy = by - ay
    a = (ax, ay)
    d = (dx, dy)
    o = (ox, oy)
    b = (bx, by)
    # the grid lines x = o + line * res (then y) strictly between the segment's ends
    first = [0, 0]
    stop = [0, 0]
    for k in range(2):
        if abs(d[k]) > 1e-12:
            lo = (a[k] - o[k]) / res
            hi = (b[k] - o[k]) / res
            if hi < lo:
                lo, hi = hi, lo
            first[k] = math.floor(lo) + 1
            stop[k] = max(first[k], math.ceil(hi))
    t = np.empty(2 + (stop[0] - first[0]) + (stop[1] - first[1]))
    t[0] = 0.0
    t[1] = 1.0
    i = 2
    for k in range(2):
        for line in range(first[k], stop[k]):
            t[i] = (o[k] + float(line) * res - a[k]) / d[k]
            i += 1
    t = np.unique(t)  # always holds 0 and 1: at least one piece
    h, w = costs.shape
    norm = math.hypot(dx, dy)
    m = t.shape[0] - 1
    lengths = np.empty(m)
    cell = np.empty(m, dtype=costs.dtype)
    for j in range(m):
        mid = 0.5 * (t[j] + t[j + 1])
        lengths[j] = (t[j + 1] - t[j]) * norm
        row = math.floor((ay + mid * dy - oy) / res)
        col = math.floor((ax + mid * dx - ox) / res)
        cell[j] = costs[row, col] if 0 <= row < h and 0 <= col < w else LETHAL
    return lengths, cell
