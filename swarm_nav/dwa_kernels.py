"""Compiled inner loops of the local planner (:mod:`swarm_nav.dwa`), with numba.

Each kernel does, pose by pose and point by point, the arithmetic that :mod:`swarm_nav.dwa` did
with numpy array expressions over all rollouts at once: the same IEEE operations on the same
operands in the same order, so the results are the same to the last bit (no ``fastmath``: LLVM
then neither reorders nor contracts them).  The transcendental functions (``sin``, ``cos``,
``arctan2``) stay in numpy, whose SIMD versions may round differently from the C library's.
What the loops gain is not arithmetic but the (S, T) temporaries and the per-call overhead of
some forty numpy calls a tick: a DWA tick of 420 rollouts x 31 poses took about 0.57 ms with numpy
and about 0.15 ms with these kernels (a replay of 29,000 recorded ticks of a 100-robot run).

Compiled on first use and cached beside this file (``cache=True``), so a process after the first
loads the machine code instead of compiling it.  :func:`warm_up` compiles them all.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def rollout_boxes(x0, y0, s0, c0, vs, ws_safe, straight, times, cos_th, sin_th, cx, cy):
    """Poses and footprint-box centres of the rollouts of every ``vs`` x ``ws`` pair.

    The arithmetic of ``dwa._fan`` and ``dwa._box_centres``: for a turning rollout ``x = x0 + v /
    w (sin th - s0)``, ``y = y0 - v / w (cos th - c0)``; for a straight one ``x = x0 + v t c0``,
    ``y = y0 + v t s0``; the box centre ``x + c cx - s cy``, ``y + s cx + c cy``.

    Args:
        x0: start x [m] in ``map``.
        y0: start y [m].
        s0: sin of the start yaw.
        c0: cos of the start yaw.
        vs: (V,) forward speeds [m/s].
        ws_safe: (W,) rotational speeds [rad/s], 1.0 where ``straight``.
        straight: (W,) bool, ``|w| < 1e-6``.
        times: (T,) times [s] after the start.
        cos_th: (W, T) cos of the yaw of rollout ``w`` at each time.
        sin_th: (W, T) sin of that yaw.
        cx: box centre x [m] in ``base_footprint``.
        cy: box centre y [m] in ``base_footprint``.

    Returns:
        ``(x, y, bx, by, bounds)``: (V * W, T) poses x, y [m] and box centres bx, by [m] in
        ``map`` (rollout ``k`` has ``vs[k // W]``, ``ws[k % W]``), and (4,) the least and
        greatest ``bx``, ``by``: ``(bx_min, bx_max, by_min, by_max)``.
    """
    nv, nw, nt = vs.shape[0], ws_safe.shape[0], times.shape[0]
    x = np.empty((nv * nw, nt))
    y = np.empty((nv * nw, nt))
    bx = np.empty((nv * nw, nt))
    by = np.empty((nv * nw, nt))
    bx_lo, bx_hi, by_lo, by_hi = math.inf, -math.inf, math.inf, -math.inf
    for i in range(nv):
        for j in range(nw):
            k = i * nw + j
            kk = vs[i] / ws_safe[j]
            for t in range(nt):
                if straight[j]:
                    vt = vs[i] * times[t]
                    xi = x0 + vt * c0
                    yi = y0 + vt * s0
                else:
                    xi = x0 + kk * (sin_th[j, t] - s0)
                    yi = y0 - kk * (cos_th[j, t] - c0)
                c = cos_th[j, t]
                s = sin_th[j, t]
                bxi = xi + c * cx - s * cy
                byi = yi + s * cx + c * cy
                x[k, t] = xi
                y[k, t] = yi
                bx[k, t] = bxi
                by[k, t] = byi
                bx_lo = min(bx_lo, bxi)
                bx_hi = max(bx_hi, bxi)
                by_lo = min(by_lo, byi)
                by_hi = max(by_hi, byi)
    return x, y, bx, by, np.array([bx_lo, bx_hi, by_lo, by_hi])


@njit(cache=True, nogil=True)
def gap_bounds(bx, by, dist, lo_x, lo_y, grid, err, r_out, r_in, need):
    """The bounds of ``dwa._gap_bounds`` from a distance grid, and which poses they cannot clear.

    Args:
        bx: (S, T) box centres x [m] in ``map``.
        by: (S, T) box centres y [m].
        dist: (H, W) distance [m] of each grid cell to the nearest obstacle point.
        lo_x: x [m] of the grid's cell (0, 0) corner.
        lo_y: y [m] of that corner.
        grid: cell size [m].
        err: the grid's error bound [m] (a cell's diagonal).
        r_out: the box's half diagonal [m].
        r_in: the box's half width [m].
        need: (S,) the gap [m] each rollout must keep.

    Returns:
        ``(lower, upper_min, est_min, unsure)``: (S, T) lower bounds of the gaps [m], (S,) each
        rollout's least upper bound [m], (S,) its least estimate for the BaseObstacle critic [m],
        and (S, T) bool, ``lower < need``.
    """
    ns, nt = bx.shape
    ncol = dist.shape[1]
    flat = dist.ravel()
    lower = np.empty((ns, nt))
    upper_min = np.empty(ns)
    est_min = np.empty(ns)
    unsure = np.empty((ns, nt), dtype=np.bool_)
    for k in range(ns):
        d_min = math.inf
        for t in range(nt):
            cell = int((by[k, t] - lo_y) / grid) * ncol + int((bx[k, t] - lo_x) / grid)
            d = flat[cell]
            d_min = min(d_min, d)
            lo = d - err - r_out
            lower[k, t] = lo
            unsure[k, t] = lo < need[k]
        upper_min[k] = d_min + err - r_in
        est_min[k] = d_min - 0.5 * (r_in + r_out)
    return lower, upper_min, est_min, unsure


@njit(cache=True, nogil=True)
def _pose_fails(bxi, byi, c, s, px, py, hx, hy, need):
    """Whether some point's Chebyshev gap to the box at one pose is below ``need`` [m]."""
    for m in range(px.shape[0]):
        dx = px[m] - bxi
        dy = py[m] - byi
        if max(abs(c * dx + s * dy) - hx, abs(c * dy - s * dx) - hy) < need:
            return True
    return False


@njit(cache=True, nogil=True)
def first_admissible(order, unsure, need, bx, by, cos_th, sin_th, px, py, hx, hy):
    """The first rollout of ``order`` whose unsure poses all keep the Chebyshev gap [m] to every
    point at least its ``need``, or -1 (``dwa._first_admissible``, checked one by one).

    Args:
        order: (K,) int candidate rollouts, cheapest first.
        unsure: (S, T) bool, poses the bounds could not clear.
        need: (S,) the gap [m] each rollout must keep.
        bx: (S, T) box centres x [m] in ``map``.
        by: (S, T) box centres y [m].
        cos_th: (W, T) cos of the yaw; rollout ``k`` has row ``k % W``.
        sin_th: (W, T) sin of the yaw.
        px: (M,) obstacle points x [m] in ``map``.
        py: (M,) obstacle points y [m].
        hx: half length [m] of the footprint box.
        hy: half width [m].
    """
    nw, nt = cos_th.shape
    for i in range(order.shape[0]):
        k = order[i]
        j = k % nw
        ok = True
        for t in range(nt):
            if unsure[k, t] and _pose_fails(bx[k, t], by[k, t], cos_th[j, t], sin_th[j, t],
                                            px, py, hx, hy, need[k]):
                ok = False
                break
        if ok:
            return k
    return -1


@njit(cache=True, nogil=True)
def rollout_min_gap(k, lower, unsure, bx, by, cos_th, sin_th, px, py, hx, hy):
    """The least gap [m] along rollout ``k``: the exact Chebyshev gap at its unsure poses, the
    lower bound at the others (``inf`` without points)."""
    nw, nt = cos_th.shape
    j = k % nw
    best = math.inf
    for t in range(nt):
        g = lower[k, t]
        if unsure[k, t]:
            g = math.inf
            c, s = cos_th[j, t], sin_th[j, t]
            for m in range(px.shape[0]):
                dx = px[m] - bx[k, t]
                dy = py[m] - by[k, t]
                g = min(g, max(abs(c * dx + s * dy) - hx, abs(c * dy - s * dx) - hy))
        best = min(best, g)
    return best


@njit(cache=True, nogil=True)
def nearest_path_dist(ex, ey, rx, ry):
    """(S,) distance [m] from each rollout end ``ex, ey`` to the nearest of the path points
    ``rx, ry`` (R,) (``dwa._path_dist``'s arithmetic: squared differences summed, then the root
    of the least)."""
    out = np.empty(ex.shape[0])
    for k in range(ex.shape[0]):
        best = math.inf
        for r in range(rx.shape[0]):
            dx = ex[k] - rx[r]
            dx *= dx
            dy = ey[k] - ry[r]
            dy *= dy
            dx += dy
            best = min(best, dx)
        out[k] = math.sqrt(best)
    return out


def warm_up() -> None:
    """Compile (or load from the cache) every kernel, on tiny inputs."""
    one = np.ones(1)
    tt = np.ones((1, 1))
    x, y, bx, by, _ = rollout_boxes(0.0, 0.0, 0.0, 1.0, one, one, np.zeros(1, dtype=np.bool_),
                                    one, tt, tt, 0.0, 0.0)
    lower, _, _, unsure = gap_bounds(bx, by, tt, -1.0, -1.0, 1.0, 0.0, 0.0, 0.0, one)
    order = np.zeros(1, dtype=np.int64)
    first_admissible(order, unsure, one, bx, by, tt, tt, one, one, 0.1, 0.1)
    rollout_min_gap(0, lower, unsure, bx, by, tt, tt, one, one, 0.1, 0.1)
    nearest_path_dist(one, one, one, one)
