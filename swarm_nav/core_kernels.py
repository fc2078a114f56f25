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
        centres, points, starts, sizes: those of ``perception.SeenArrays``: (K, 2) centres x, y
            [m] in ``map`` of the robots seen, (P, 2) their points [m], robot after robot, (K,)
            each robot's first row in ``points`` and its number of points.
        ax, ay: (A,) x, y [m] of the path points ahead, A >= 1; rx, ry: the robot's x, y [m].
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


_SLACK = 1e-9  # [m] or [rad]: what rounding may differ by between this kernel and numpy


@njit(cache=True, nogil=True)
def may_keep_right(centres, velocities, rx, ry, ryaw, moving_speed, distance, half_angle,
                   px, py, lateral):
    """Whether :func:`swarm_nav.traffic.keep_right` of the robots coming toward us may shift the
    path: some robot seen drives toward us faster than ``moving_speed``, lies within
    ``distance`` and ``half_angle`` ahead, and within ``lateral`` of a path point.

    The tests of :func:`~swarm_nav.traffic.oncoming_centres`, :func:`~swarm_nav.traffic.
    robots_ahead` and ``keep_right``, with ``_SLACK`` added to the limits: when this says False,
    ``keep_right`` returns the path unchanged (most robots, most ticks); when True, the caller
    runs it (``tests/swarm_nav/test_traffic.py`` checks that False is never wrong).

    Args:
        centres, velocities: (K, 2) centres x, y [m] in ``map`` of the robots seen and their
            velocities [m/s] (NaN: unknown).
        rx, ry, ryaw: our pose x, y [m] in ``map``, yaw [rad].
        moving_speed: [m/s] the speed toward us above which a robot is oncoming.
        distance: [m] how far ahead a robot counts; half_angle: [rad] half the opening of the
            cone ahead.
        px, py: (N,) x, y [m] of the local path's points; lateral: [m] how near the path a
            robot counts as on it.
    """
    for j in range(centres.shape[0]):
        cx, cy = centres[j, 0], centres[j, 1]
        vx, vy = velocities[j, 0], velocities[j, 1]
        if not (math.isfinite(vx) and math.isfinite(vy)):
            continue
        dx, dy = rx - cx, ry - cy
        n = math.hypot(dx, dy)
        if n <= 1e-6 or (vx * dx + vy * dy) / n <= moving_speed - _SLACK:
            continue
        if n > distance + _SLACK:
            continue
        a = math.atan2(-dy, -dx) - ryaw
        bearing = abs(a - 2.0 * math.pi * math.floor((a + math.pi) / (2.0 * math.pi)))
        if bearing > half_angle + _SLACK:
            continue
        for i in range(px.shape[0]):
            if math.hypot(cx - px[i], cy - py[i]) <= lateral + _SLACK:
                return True
    return False
