"""The compiled inner loop of the planar lidar (:mod:`swarm_sim.lidar`), with numba.

:meth:`~swarm_sim.lidar.PlanarLidar.true_ranges` finds, for every (lidar, segment) pair within
range, the beams inside the angle the segment subtends, and intersects each of those beams with
the segment.  With numpy that expanded the pairs into some 10^5 (lidar, beam, segment) triples a
scan at 100 robots and ran a score of array expressions over them; here one loop walks the pairs
and their beams and keeps each beam's nearest hit, with no temporaries.  Every value is computed
with the same IEEE operations on the same operands in the same order as the numpy expressions
(no ``fastmath``: LLVM neither reorders nor contracts them), so the ranges are the same to the
last bit (``tests/swarm_sim/test_lidar.py`` holds the kernel against a frozen copy of the numpy
code).  The transcendental functions (the bearings' ``arctan2``, the lidars' ``cos`` and
``sin``) stay in numpy.

Compiled on first use and cached beside this file (``cache=True``); every
:class:`~swarm_sim.lidar.PlanarLidar` calls :func:`warm_up` when it is built.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

TWO_PI = 2.0 * math.pi


@njit(cache=True, nogil=True)
def cast_pairs(lo, hi, lid, segs, ox, oy, cos_lidar, sin_lidar, cos_beam, sin_beam, inc, out):
    """Nearest hit of every beam over the (lidar, segment) pairs, written into ``out``.

    Args:
        lo: (P,) [rad] start of the arc pair ``p``'s segment subtends, as an offset from the
            first beam's angle, widened by 1e-9 (``PlanarLidar._arcs``).
        hi: (P,) [rad] its end (``lo`` plus the arc's width plus 2e-9).
        lid: (P,) the lidar of each pair.
        segs: (P, 4) the segment of each pair, ``x0, y0, x1, y1`` [m] in ``map``.
        ox: (N,) lidar origins x [m].
        oy: (N,) lidar origins y [m].
        cos_lidar: (N,) cos of each lidar's yaw.
        sin_lidar: (N,) sin of each lidar's yaw.
        cos_beam: (B,) cos of each beam's angle in the lidar frame.
        sin_beam: (B,) sin of each beam's angle.
        inc: angle between beams [rad] (2 pi for a single beam).
        out: (N * B,) distances [m], ``inf`` where nothing was hit yet; lowered in place.
    """
    n_beams = cos_beam.shape[0]
    for p in range(lo.shape[0]):
        li = lid[p]
        x0, y0, x1, y1 = segs[p, 0], segs[p, 1], segs[p, 2], segs[p, 3]
        px = x0 - ox[li]
        py = y0 - oy[li]
        ex = x1 - x0
        ey = y1 - y0
        cy, sy = cos_lidar[li], sin_lidar[li]
        # The arc may wrap past the first beam + 2 pi (shift 2 pi), and the beams may reach past
        # it too (Gazebo's 0..6.28319 puts the last beam 4.7e-6 rad beyond 2 pi: shift -2 pi).
        for shift in (-TWO_PI, 0.0, TWO_PI):
            k0 = max(math.ceil((lo[p] - shift) / inc), 0)
            k1 = min(math.floor((hi[p] - shift) / inc), n_beams - 1)
            for k in range(k0, k1 + 1):
                ca, sa = cos_beam[k], sin_beam[k]
                dx = cy * ca - sy * sa
                dy = sy * ca + cy * sa
                denom = dx * ey - dy * ex
                if abs(denom) > 1e-12:
                    t = (px * ey - py * ex) / denom
                    u = (px * dy - py * dx) / denom
                    if t >= 0.0 and u >= 0.0 and u <= 1.0:
                        j = li * n_beams + k
                        if t < out[j]:
                            out[j] = t


def warm_up() -> None:
    """Compile :func:`cast_pairs` (or load it from the cache) with a real run's argument types,
    so that the first scan is not held up by it (about 2 s on a fresh machine)."""
    out = np.full(2, np.inf)
    cast_pairs(np.zeros(1), np.ones(1), np.zeros(1, dtype=np.intp),
               np.array([[1.0, -1.0, 1.0, 1.0]]), np.zeros(1), np.zeros(1), np.ones(1),
               np.zeros(1), np.array([1.0, 0.0]), np.array([0.0, 1.0]), 1.0, out)
