"""Compiled inner loops of the navigator's tick (:mod:`swarm_nav.core`), with numba.

The same IEEE operations in the same order as the numpy expressions they replace, so the answers
are the same to the last bit (see :mod:`swarm_nav.dwa_kernels` for the rules); what they save is
the per-call overhead of numpy on arrays of tens of points, paid by every robot every tick.
Compiled on first use and cached beside this file.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def robots_near_path(centres, points, starts, sizes, ax, ay, rx, ry, reach, radius):
    """The robots seen with a point within ``radius`` of the stretch of path ahead.

    Only robots whose centre is within ``reach`` of the robot are checked; a robot is on the path
    when the least Euclidean distance between one of its points and one of the path points is
    below ``radius``.

    Args:
        centres: (K, 2) centres x, y [m] in ``map`` of the robots seen.
        points: (P, 2) their points x, y [m], robot after robot.
        starts: (K,) each robot's first row in ``points``.
        sizes: (K,) each robot's number of points.
        ax: (A,) x [m] of the path points ahead, A >= 1.
        ay: (A,) y [m] of those points.
        rx: the robot's x [m] in ``map``.
        ry: the robot's y [m].
        reach: [m] the farthest a robot's centre may be to be checked.
        radius: [m] the distance below which a point is on the path.

    Returns:
        (J,) int, the indices of the robots on the path, ascending.
    """
    out = np.empty(centres.shape[0], dtype=np.int64)
    n = 0
    for j in range(centres.shape[0]):
        if not math.hypot(centres[j, 0] - rx, centres[j, 1] - ry) <= reach:
            continue
        hit = False
        for p in range(starts[j], starts[j] + sizes[j]):
            for a in range(ax.shape[0]):
                if math.hypot(points[p, 0] - ax[a], points[p, 1] - ay[a]) < radius:
                    hit = True
                    break
            if hit:
                break
        if hit:
            out[n] = j
            n += 1
    return out[:n]
