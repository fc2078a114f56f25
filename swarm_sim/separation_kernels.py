"""The compiled pair loop of the simulator's minimum separation (:mod:`swarm_sim.engine`), with
numba.

Every tick the engine measures the distance between the footprints of every pair of robots near
each other (``SimEngine._update_min_separation``).  With numpy that was some twenty array
expressions over (pairs, vertices, edges) temporaries: 8-9 % of the simulator's CPU at 100
robots, on the lockstep tick's critical path (the navigators wait while the simulator steps).
Here one loop walks the pairs with the arithmetic of that numpy code
(``tests/swarm_sim/test_engine.py`` holds the kernel against a frozen copy of it, bit for bit);
:func:`swarm_sim.engine.polygon_distances` is this kernel.

Compiled on first use and cached beside this file (``cache=True``); :class:`swarm_sim.engine.
SimEngine` calls :func:`warm_up` when it is built.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def _vertex_edge(a, b):
    """Least distance [m] from a vertex of polygon ``a`` to an edge of polygon ``b``, and
    whether a vertex of ``a`` lies strictly inside ``b`` (both (K, 2), convex, one winding; a
    polygon padded by repeating a vertex, as a mixed fleet's are, has zero-length edges that the
    inside test skips)."""
    best = math.inf
    inside = False
    kb = b.shape[0]
    for v in range(a.shape[0]):
        pos = True
        neg = True
        for k in range(kb):
            ex = b[(k + 1) % kb, 0] - b[k, 0]
            ey = b[(k + 1) % kb, 1] - b[k, 1]
            rx = a[v, 0] - b[k, 0]
            ry = a[v, 1] - b[k, 1]
            len2 = max(ex * ex + ey * ey, 1e-18)
            u = min(max((rx * ex + ry * ey) / len2, 0.0), 1.0)
            dx = rx - u * ex
            dy = ry - u * ey
            best = min(best, math.sqrt(dx * dx + dy * dy))
            if ex != 0.0 or ey != 0.0:  # a padding vertex's zero-length edge says nothing
                cross = ex * ry - ey * rx
                pos = pos and cross > 0.0
                neg = neg and cross < 0.0
        inside = inside or pos or neg
    return best, inside


@njit(cache=True, nogil=True)
def pair_distances(a, b):
    """Distances [m] between the convex polygons ``a[p]`` and ``b[p]`` of every pair ``p``.

    Args:
        a: (P, K, 2) polygons x, y [m] (the robots' footprints in ``map``), one winding,
            fewer vertices padded by repeating one.
        b: (P, K, 2) the other polygon of each pair.

    Returns:
        (P,) the least vertex-to-edge distance either way, 0 for polygons that overlap (a vertex
        of one strictly inside the other).
    """
    out = np.empty(a.shape[0])
    for p in range(a.shape[0]):
        dab, ia = _vertex_edge(a[p], b[p])
        dba, ib = _vertex_edge(b[p], a[p])
        out[p] = 0.0 if ia or ib else min(dab, dba)
    return out


def warm_up() -> None:
    """Compile :func:`pair_distances`, or load it from numba's cache."""
    square = np.array([[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]])
    pair_distances(square, square + 2.0)
