"""Compiled loops of the navigator's perception (:mod:`swarm_nav.perception`), with numba.

Each kernel does, point by point, the arithmetic that :mod:`swarm_nav.perception` did with numpy
(and a scipy k-d tree) over whole arrays, with the same results to the last bit (the rules:
:mod:`swarm_nav.dwa_kernels`; ``hypot`` is the C library's in both numpy and numba).  What the
loops gain is not arithmetic but the per-call overhead of some forty numpy and scipy calls on
small arrays (tens to a few hundred points) at every scan of every robot (a fifth of the time:
docs/design/navigator.md#compiled-kernels; tests/swarm_nav/test_perception_kernels.py holds the
equivalence).

Single linkage: two points are linked when ``dx * dx + dy * dy <= link * link``, the test of
scipy's ``cKDTree.query_pairs`` at its leaves (it compares squared distances, summed from 0 in
the order x, y).  The pairs are found by a sweep over the points sorted by x, which stops once
``dx * dx`` alone exceeds ``link * link``.

Compiled on first use and cached beside this file (:mod:`swarm_nav.jit` warms them all up).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def dynamic_mask(pts, ox, oy, resolution, distance, tolerance):
    """Which points lie farther than ``tolerance`` from every lethal cell of a costmap.

    The arithmetic of ``Costmap.distance_at``: cell ``(floor((y - oy) / res), floor((x - ox) /
    res))``, its ``distance`` there (0 off the grid), compared with ``> tolerance``.

    Args:
        pts: (M, 2) x, y [m] in ``map`` (C-contiguous).
        ox, oy: x, y [m] of the grid's cell (0, 0) corner in ``map``; resolution: cell size [m].
        distance: (H, W) float32 distance [m] of each cell to the nearest lethal cell.
        tolerance: the distance [m] a point must exceed.

    Returns:
        ``(keep, ok)``: (M,) bool mask of the dynamic points, and False when a cell index was
        not a finite number of int64 range (NaN, inf or huge coordinates: the caller then
        takes numpy's path, whose casts of such values are undefined).
    """
    m = pts.shape[0]
    h, w = distance.shape
    keep = np.empty(m, dtype=np.bool_)
    for i in range(m):
        fc = math.floor((pts[i, 0] - ox) / resolution)
        fr = math.floor((pts[i, 1] - oy) / resolution)
        if not (-4.0e18 < fc < 4.0e18 and -4.0e18 < fr < 4.0e18):
            return keep, False
        col = int(fc)
        row = int(fr)
        d = 0.0
        if row >= 0 and row < h and col >= 0 and col < w:
            d = float(distance[row, col])
        keep[i] = d > tolerance
    return keep, True


@njit(cache=True, nogil=True)
def _root(parent, i):
    """The root of ``i`` in the union-find forest ``parent``, halving the path on the way."""
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@njit(cache=True, nogil=True)
def cluster_labels(pts, link):
    """Single-linkage clusters of points, numbered in the order of their first point.

    Args:
        pts: (M, 2) x, y [m] (C-contiguous).
        link: the linking distance [m]: points with ``dx * dx + dy * dy <= link * link`` are
            linked (as ``cKDTree.query_pairs``).

    Returns:
        ``(labels, n)``: (M,) int64 cluster index of each point, and the number of clusters;
        ``n`` is -1 when M > 1 and a coordinate is not finite (``cKDTree`` refuses those).
    """
    m = pts.shape[0]
    r2 = link * link
    labels = np.zeros(m, dtype=np.int64)
    if m <= 1:
        return labels, m
    for i in range(m):
        if not (math.isfinite(pts[i, 0]) and math.isfinite(pts[i, 1])):
            return labels, -1
    parent = np.arange(m)
    order = np.argsort(pts[:, 0])
    for a in range(m):
        i = order[a]
        xi = pts[i, 0]
        yi = pts[i, 1]
        for b in range(a + 1, m):
            j = order[b]
            dx = xi - pts[j, 0]
            dx2 = dx * dx
            if dx2 > r2:  # x sorted: every later point is at least as far along x
                break
            dy = yi - pts[j, 1]
            if dx2 + dy * dy <= r2:
                ri = _root(parent, i)
                rj = _root(parent, j)
                if ri < rj:  # the root of a cluster is its first point
                    parent[rj] = ri
                elif rj < ri:
                    parent[ri] = rj
    n = 0
    for i in range(m):  # a root comes before the other points of its cluster
        r = _root(parent, i)
        if r == i:
            labels[i] = n
            n += 1
        else:
            labels[i] = labels[r]
    return labels, n


@njit(cache=True, nogil=True)
def cluster_centres(pts, labels, n, vx, vy, depth):
    """The centres of clusters of points: centroids pushed ``depth`` away from a viewer.

    The arithmetic of the numpy code it replaced: sums accumulated point by point in the order
    of ``pts`` (as ``np.add.at``), divided by the counts; then ``centroid + depth * away /
    max(|away|, 1e-9)`` with ``away = centroid - viewer``.

    Args:
        pts: (M, 2) x, y [m] in ``map``; labels: (M,) int cluster index of each point (0 to
            n - 1); n: the number of clusters.
        vx, vy: the viewer's x, y [m] in ``map``.
        depth: how far behind its centroid [m] a cluster's centre lies.

    Returns:
        (n, 2) centres x, y [m] in ``map``.
    """
    sums = np.zeros((n, 2))
    counts = np.zeros(n, dtype=np.int64)
    for i in range(pts.shape[0]):
        k = labels[i]
        sums[k, 0] += pts[i, 0]
        sums[k, 1] += pts[i, 1]
        counts[k] += 1
    out = np.empty((n, 2))
    for k in range(n):
        c = float(counts[k])
        cx = sums[k, 0] / c
        cy = sums[k, 1] / c
        ax = cx - vx
        ay = cy - vy
        norm = math.hypot(ax, ay)
        if norm < 1e-9:  # np.maximum(norm, 1e-9): NaN stays NaN
            norm = 1e-9
        out[k, 0] = cx + depth * ax / norm
        out[k, 1] = cy + depth * ay / norm
    return out


@njit(cache=True, nogil=True)
def match_velocities(centres, earlier, dt, reach):
    """Velocities of centres from the nearest centre of an earlier scan.

    The arithmetic of the numpy code it replaced: ``hypot`` distances, the first least
    one (a NaN distance counts as least, as ``np.argmin``), accepted when ``<= reach``, the
    velocity ``(centre - earlier) / dt``.

    Args:
        centres: (K, 2) centres x, y [m] now; earlier: (J, 2) centres [m] ``dt`` seconds earlier.
        dt: the time between them [s] (> 0); reach: the farthest [m] a match may be.

    Returns:
        (K, 2) velocities [m/s]; NaN where no earlier centre matched (all NaN when J is 0).
    """
    nk = centres.shape[0]
    nj = earlier.shape[0]
    out = np.full((nk, 2), np.nan)
    if nj == 0:
        return out
    for k in range(nk):
        cx = centres[k, 0]
        cy = centres[k, 1]
        best = math.hypot(cx - earlier[0, 0], cy - earlier[0, 1])
        jb = 0
        if not math.isnan(best):
            for j in range(1, nj):
                d = math.hypot(cx - earlier[j, 0], cy - earlier[j, 1])
                if math.isnan(d):
                    best = d
                    jb = j
                    break
                if d < best:
                    best = d
                    jb = j
        if best <= reach:
            out[k, 0] = (cx - earlier[jb, 0]) / dt
            out[k, 1] = (cy - earlier[jb, 1]) / dt
    return out


@njit(cache=True, nogil=True)
def group_points(pts, labels, n):
    """The points cluster after cluster, each cluster's in the order of ``pts``.

    Args:
        pts: (M, 2) x, y [m]; labels: (M,) int cluster index of each point (0 to n - 1); n: the
            number of clusters.

    Returns:
        ``(grouped, starts, sizes)``: (M, 2) the points, (n,) int64 index of each cluster's
        first point in ``grouped`` and (n,) int64 its number of points.
    """
    m = pts.shape[0]
    sizes = np.zeros(n, dtype=np.int64)
    for i in range(m):
        sizes[labels[i]] += 1
    starts = np.zeros(n, dtype=np.int64)
    for k in range(1, n):
        starts[k] = starts[k - 1] + sizes[k - 1]
    fill = starts.copy()
    grouped = np.empty((m, 2))
    for i in range(m):
        k = labels[i]
        grouped[fill[k], 0] = pts[i, 0]
        grouped[fill[k], 1] = pts[i, 1]
        fill[k] += 1
    return grouped, starts, sizes


@njit(cache=True, nogil=True)
def finite_rows(pts):
    """The rows of ``pts`` (M, 2) whose two coordinates are finite, in order, as a new (K, 2)
    array (``pts[np.all(np.isfinite(pts), axis=1)]``)."""
    m = pts.shape[0]
    keep = np.empty(m, dtype=np.bool_)
    k = 0
    for i in range(m):
        ok = math.isfinite(pts[i, 0]) and math.isfinite(pts[i, 1])
        keep[i] = ok
        k += ok
    out = np.empty((k, 2))
    j = 0
    for i in range(m):
        if keep[i]:
            out[j, 0] = pts[i, 0]
            out[j, 1] = pts[i, 1]
            j += 1
    return out


@njit(cache=True, nogil=True)
def speeds(velocity):
    """``(known, speed)`` of (K, 2) velocities [m/s]: (K,) bool, both components finite, and
    (K,) their ``hypot`` [m/s] where known, 0 elsewhere (``SeenArrays``' arithmetic)."""
    k = velocity.shape[0]
    known = np.empty(k, dtype=np.bool_)
    speed = np.empty(k)
    for i in range(k):
        ok = math.isfinite(velocity[i, 0]) and math.isfinite(velocity[i, 1])
        known[i] = ok
        speed[i] = math.hypot(velocity[i, 0], velocity[i, 1]) if ok else 0.0
    return known, speed


@njit(cache=True, nogil=True)
def moving_points(points, starts, sizes, velocity, moving):
    """The points of the moving robots, each robot's twice
    (``swarm_nav.perception.ObstacleSet._moving_points``).

    Args:
        points, starts, sizes, velocity: those of ``perception.SeenArrays``: (P, 2) points x, y
            [m] in ``map``, robot after robot, (K,) int each robot's first point and number of
            points, (K, 2) its velocity [m/s].
        moving: (K,) bool, the robots to take.

    Returns:
        ``(pts, vel, later)``: robot after robot, its points for the earlier time, then the
        same points for the later one: (Q, 2) x, y [m], (Q, 2) the robot's velocity [m/s] and
        (Q,) bool, whether the row is for the later time.
    """
    q = 0
    for k in range(starts.shape[0]):
        if moving[k]:
            q += 2 * sizes[k]
    pts = np.empty((q, 2))
    vel = np.empty((q, 2))
    later = np.empty(q, dtype=np.bool_)
    j = 0
    for k in range(starts.shape[0]):
        if not moving[k]:
            continue
        for copy in range(2):
            for i in range(starts[k], starts[k] + sizes[k]):
                pts[j, 0] = points[i, 0]
                pts[j, 1] = points[i, 1]
                vel[j, 0] = velocity[k, 0]
                vel[j, 1] = velocity[k, 1]
                later[j] = copy == 1
                j += 1
    return pts, vel, later


@njit(cache=True, nogil=True)
def perceive(pts, link, vx, vy, depth, earlier, dt, reach):
    """Clusters, centres, velocities and grouped points of one scan's dynamic points.

    :func:`cluster_labels`, :func:`cluster_centres`, :func:`match_velocities` (when ``earlier``
    has rows and ``dt > 0``; NaN velocities otherwise) and :func:`group_points` in one call.

    Args:
        pts, link: as :func:`cluster_labels` (the dynamic points [m] in ``map``).
        vx, vy, depth: as :func:`cluster_centres` [m].
        earlier, dt, reach: as :func:`match_velocities` (J may be 0) [m], [s], [m].

    Returns:
        ``(n, centres, velocity, grouped, starts, sizes, owner, known, speed)``: the number of
        clusters, (n, 2) centres [m], (n, 2) velocities [m/s] (NaN: unknown),
        :func:`group_points`'s arrays, (M,) int64 the cluster of each grouped point, and
        :func:`speeds`; ``n`` is -1 (and the arrays empty) when :func:`cluster_labels` refuses
        the points.
    """
    labels, n = cluster_labels(pts, link)
    if n < 0:
        z = np.zeros((0, 2))
        e = np.zeros(0, dtype=np.int64)
        return n, z, z, z, e, e, e, np.zeros(0, dtype=np.bool_), np.zeros(0)
    centres = cluster_centres(pts, labels, n, vx, vy, depth)
    if n > 0 and earlier.shape[0] > 0 and dt > 0:
        vel = match_velocities(centres, earlier, dt, reach)
    else:
        vel = np.full((n, 2), np.nan)
    grouped, starts, sizes = group_points(pts, labels, n)
    owner = np.empty(pts.shape[0], dtype=np.int64)
    for k in range(n):
        owner[starts[k]:starts[k] + sizes[k]] = k
    known, speed = speeds(vel)
    return n, centres, vel, grouped, starts, sizes, owner, known, speed
