"""Compiled inner loops of the local planner (:mod:`swarm_nav.dwa`), with numba.

Each kernel does, pose by pose and point by point, the arithmetic that :mod:`swarm_nav.dwa` did
with numpy array expressions over all rollouts at once: the same IEEE operations on the same
operands in the same order, so the results are the same to the last bit (no ``fastmath``: LLVM
then neither reorders nor contracts them).  The transcendental functions (``sin``, ``cos``,
``arctan2``) stay in numpy, whose SIMD versions may round differently from the C library's.
What the loops gain is not arithmetic but the (S, T) temporaries and the per-call overhead of
some forty numpy calls a tick, half of a DWA call's time
(docs/design/navigator.md#compiled-kernels).

Compiled on first use and cached beside this file (``cache=True``): a process after the first
loads the machine code (:mod:`swarm_nav.jit` warms them all up).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, nogil=True)
def rollout_boxes(x0, y0, s0, c0, vs, ws, ws_safe, straight, times, cos_th, sin_th, cx, cy,
                  radius, dt_check, need):
    """Poses and footprint-box centres of the rollouts of every ``vs`` x ``ws`` pair, and the
    gap each rollout must keep.

    Exact unicycle arcs (``tests/swarm_nav/helpers.rollout``, and ``dwa._box_centres``): for a
    turning rollout ``x = x0 + v / w (sin th - s0)``, ``y = y0 - v / w (cos th - c0)``; for a
    straight one ``x = x0 + v t c0``, ``y = y0 + v t s0``; the box centre ``x + c cx - s cy``,
    ``y + s cx + c cy``.

    Args:
        x0, y0: start x, y [m] in ``map``; s0, c0: sin and cos of the start yaw.
        vs: (V,) forward speeds [m/s]; ws: (W,) rotational speeds [rad/s].
        ws_safe: (W,) ``ws``, 1.0 where ``straight``; straight: (W,) bool, ``|w| < 1e-6``.
        times: (T,) times [s] after the start.
        cos_th, sin_th: (W, T) cos and sin of the yaw of rollout ``w`` at each time.
        cx, cy: box centre x, y [m] in ``base_footprint``.
        radius: the box's circumscribed radius [m] about ``base_footprint``.
        dt_check: time [s] between two checked poses.
        need: the gap [m] to keep at the checked poses.

    Returns:
        ``(x, y, bx, by, bounds, need_s)``: (V * W, T) poses x, y [m] and box centres bx, by [m]
        in ``map`` (rollout ``k`` has ``vs[k // W]``, ``ws[k % W]``); (4,) the least and
        greatest ``bx``, ``by``: ``(bx_min, bx_max, by_min, by_max)``; and (V * W,) the gap
        [m] each rollout must keep at its checked poses, ``need + step / 2`` with ``step = (|v| +
        |w| radius) dt_check`` the farthest a point of the box moves between two of them.
    """
    nv, nw, nt = vs.shape[0], ws_safe.shape[0], times.shape[0]
    x = np.empty((nv * nw, nt))
    y = np.empty((nv * nw, nt))
    bx = np.empty((nv * nw, nt))
    by = np.empty((nv * nw, nt))
    need_s = np.empty(nv * nw)
    bx_lo, bx_hi, by_lo, by_hi = math.inf, -math.inf, math.inf, -math.inf
    for i in range(nv):
        for j in range(nw):
            k = i * nw + j
            need_s[k] = need + 0.5 * ((abs(vs[i]) + abs(ws[j]) * radius) * dt_check)
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
    return x, y, bx, by, np.array([bx_lo, bx_hi, by_lo, by_hi]), need_s


@njit(cache=True, nogil=True)
def _squared_edt_1d(f, n, out, v, z):
    """The exact 1-D squared distance transform of ``f[:n]`` (``inf``: no feature) into ``out``
    (the lower envelope of parabolas of Felzenszwalb and Huttenlocher 2012, over the finite
    entries only); ``v``, ``z`` are work arrays of ``n`` and ``n + 1``."""
    k = -1
    for q in range(n):
        if f[q] == math.inf:
            continue
        fq = f[q] + q * q
        while k >= 0:
            p = v[k]
            s = (fq - (f[p] + p * p)) / (2 * q - 2 * p)
            if s <= z[k]:
                k -= 1
            else:
                break
        if k < 0:
            k = 0
            z[0] = -math.inf
        else:
            p = v[k]
            k += 1
            z[k] = (fq - (f[p] + p * p)) / (2 * q - 2 * p)
        v[k] = q
    if k < 0:
        for q in range(n):
            out[q] = math.inf
        return
    z[k + 1] = math.inf
    j = 0
    for q in range(n):
        while z[j + 1] < q:
            j += 1
        p = v[j]
        out[q] = (q - p) * (q - p) + f[p]


@njit(cache=True, nogil=True)
def squared_distance_grid(rows, cols, h, w):
    """(h, w) the exact squared distance [cells^2] of every cell to the nearest of the feature
    cells ``rows[m], cols[m]`` (what ``scipy.ndimage.distance_transform_edt`` squares: an
    integer, exact in float64)."""
    d2 = np.empty((h, w))
    col = np.empty(h)
    f = np.full(h, math.inf)
    out = np.empty(max(h, w))
    v = np.empty(max(h, w), dtype=np.int64)
    z = np.empty(max(h, w) + 1)
    feat = np.zeros((h, w), dtype=np.bool_)
    for m in range(rows.shape[0]):
        feat[rows[m], cols[m]] = True
    for c in range(w):
        for r in range(h):
            f[r] = 0.0 if feat[r, c] else math.inf
        _squared_edt_1d(f, h, col, v, z)
        for r in range(h):
            d2[r, c] = col[r]
    for r in range(h):
        _squared_edt_1d(d2[r], w, out, v, z)
        for c in range(w):
            d2[r, c] = out[c]
    return d2


@njit(cache=True, nogil=True)
def gap_bounds(bx, by, box_bounds, px, py, grid, r_out, r_in, need):
    """Cheap bounds of the gaps [m] between the footprint at the rollout poses and the points,
    and which poses they cannot clear.

    A distance transform of the points on a local grid gives every box centre's distance ``d`` to
    the nearest point within ``e = sqrt(2)`` grid cells.  The gap is at least ``d - e - R`` (``R``
    the box's half diagonal) and at most ``d + e - r`` (``r`` its half width, the nearest point
    being at most that far inside the box's inscribed circle).  (Rounding is monotonic, so the
    minimum of ``d + c`` over a rollout is ``min(d) + c``, bit for bit.)

    The points are marked on a grid of ``grid`` cells spanning them and the box centres with a
    margin of two cells; ``d``, a box centre's distance to the nearest marked cell (the exact
    Euclidean distance transform, as ``scipy.ndimage.distance_transform_edt``), is within ``e =
    sqrt(2) grid`` of its distance to the nearest point.

    Args:
        bx, by: (S, T) box centres x, y [m] in ``map``.
        box_bounds: (4,) ``(bx_min, bx_max, by_min, by_max)`` [m].
        px, py: (M,) obstacle points x, y [m] in ``map``, M > 0.
        grid: cell size [m].
        r_out, r_in: the box's half diagonal and half width [m].
        need: (S,) the gap [m] each rollout must keep.

    Returns:
        ``(lower, upper_min, est_min, unsure)``: (S, T) lower bounds ``d - e - r_out`` of the
        gaps [m], (S,) each rollout's least upper bound ``min d + e - r_in`` [m], (S,) its least
        estimate for the BaseObstacle critic ``min d - (r_in + r_out) / 2`` [m], and (S, T)
        bool, ``lower < need``.
    """
    lo_x = min(box_bounds[0], px.min()) - 2 * grid
    lo_y = min(box_bounds[2], py.min()) - 2 * grid
    hi_x = max(box_bounds[1], px.max()) + 2 * grid
    hi_y = max(box_bounds[3], py.max()) + 2 * grid
    h = math.ceil((hi_y - lo_y) / grid) + 1
    w = math.ceil((hi_x - lo_x) / grid) + 1
    rows = np.empty(px.shape[0], dtype=np.int64)
    cols = np.empty(px.shape[0], dtype=np.int64)
    for m in range(px.shape[0]):
        rows[m] = int((py[m] - lo_y) / grid)
        cols[m] = int((px[m] - lo_x) / grid)
    d2 = squared_distance_grid(rows, cols, h, w)
    err = grid * math.sqrt(2.0)
    ns, nt = bx.shape
    lower = np.empty((ns, nt))
    upper_min = np.empty(ns)
    est_min = np.empty(ns)
    unsure = np.empty((ns, nt), dtype=np.bool_)
    for k in range(ns):
        d_min = math.inf
        for t in range(nt):
            d = math.sqrt(d2[int((by[k, t] - lo_y) / grid), int((bx[k, t] - lo_x) / grid)]) * grid
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
    point at least its ``need``, or -1 (checked one by one).

    Args:
        order: (K,) int candidate rollouts, cheapest first.
        unsure: (S, T) bool, poses the bounds could not clear.
        need: (S,) the gap [m] each rollout must keep.
        bx, by: (S, T) box centres x, y [m] in ``map``.
        cos_th, sin_th: (W, T) cos and sin of the yaw; rollout ``k`` has row ``k % W``.
        px, py: (M,) obstacle points x, y [m] in ``map``.
        hx, hy: half length and half width [m] of the footprint box.
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
def score_rollouts(x, y, aim_end, th_end, vs, ws, rx, ry, carrot_x, carrot_y, tangent, px, py,
                   to_path, i0, est_min, upper_min, need, max_vel_x, influence, scales):
    """The weighted cost of every rollout (the critics of :mod:`swarm_nav.dwa`), and the
    candidates to check, cheapest first.

    Args:
        x, y: (S, T) rollout poses x, y [m] in ``map``; rollout ``k`` has ``vs[k // W]``,
            ``ws[k % W]``.
        aim_end: (S,) ``arctan2`` [rad] of each rollout end's offset to the carrot (numpy's,
            whose rounding the kernels do not reproduce).
        th_end: (W,) yaw [rad] at the rollouts' end per ``ws`` sample.
        vs: (V,) forward speeds [m/s]; ws: (W,) rotational speeds [rad/s].
        rx, ry: the robot's x, y [m] in ``map``.
        carrot_x, carrot_y: x, y [m] of the lookahead point; tangent: the path's heading [rad]
            there.
        px, py: (N,) path points x, y [m] in ``map``; to_path: (N,) their distance [m] to the
            robot; i0: index of the one nearest the robot.
        est_min, upper_min: (S,) each rollout's least gap estimate and upper bound [m]
            (:func:`gap_bounds`); need: (S,) the gap [m] each rollout must keep.
        max_vel_x: [m/s], for the Speed critic; influence: BaseObstacle's influence distance
            [m]; scales: (5,) weights of PathDist, GoalDist, PathAlign, BaseObstacle, Speed.

    Returns:
        ``(cost, order)``: (S,) weighted costs, and (K,) the rollouts that move and whose upper
        bound does not already rule them out, by cost (stable: ties keep rollout order).
    """
    ns, nt = x.shape
    nw = ws.shape[0]
    # PathDist compares each end only with the path points that can be its nearest: with every
    # end within `reach` of the robot, a point farther than 2 reach + to_path[i0] from the robot
    # is farther from every end than the point i0
    reach = -math.inf
    for k in range(ns):
        reach = max(reach, math.hypot(x[k, nt - 1] - rx, y[k, nt - 1] - ry))
    limit = 2.0 * reach + to_path[i0] + 1e-6
    near = np.empty(px.shape[0] - i0, dtype=np.int64)
    n_near = 0
    for r in range(i0, px.shape[0]):
        if to_path[r] <= limit:
            near[n_near] = r
            n_near += 1
    cost = np.empty(ns)
    keep = np.empty(ns, dtype=np.bool_)
    for k in range(ns):
        v = vs[k // nw]
        w = ws[k % nw]
        ex = x[k, nt - 1]
        ey = y[k, nt - 1]
        best = math.inf
        for i in range(n_near):
            dx = ex - px[near[i]]
            dx *= dx
            dy = ey - py[near[i]]
            dy *= dy
            dx += dy
            best = min(best, dx)
        path_dist = math.sqrt(best)
        goal_dist = math.hypot(carrot_x - ex, carrot_y - ey)
        aim = aim_end[k] if goal_dist > 0.15 else tangent
        turn = th_end[k % nw] - aim
        align = abs(math.pi - ((math.pi - turn) % (2.0 * math.pi)))
        obst = min(max((influence - est_min[k]) / influence, 0.0), 1.0) ** 2
        speed = (max_vel_x - v) / max_vel_x
        cost[k] = (scales[0] * path_dist + scales[1] * goal_dist + scales[2] * align
                   + scales[3] * obst + scales[4] * speed)
        keep[k] = (abs(v) > 1e-9 or abs(w) > 1e-9) and not upper_min[k] < need[k]
    cand = np.flatnonzero(keep)
    return cost, cand[np.argsort(cost[cand], kind="mergesort")]


# ---------------------------------------------------------------- one DWA tick in three calls
# dwa.dwa_command calls these three in turn, with numpy's sin, cos and arctan2 between them (their
# SIMD rounding is not the C library's): the numpy glue between more, smaller kernels cost more
# than the kernels (docs/design/navigator.md#compiled-kernels).


@njit(cache=True, nogil=True)
def window_setup(x0, y0, th0, ws, horizon, n, obstacles, radius, c, s, cx, cy, hx, hy):
    """The rollout times and headings, the obstacle points within reach, and the gap now.

    Args:
        x0, y0, th0: the robot's pose x, y [m], yaw [rad] in ``map``.
        ws: (W,) rotational speeds [rad/s].
        horizon: the rollouts' duration [s]; n: the number of checked poses along a rollout.
        obstacles: (M, 2) obstacle points x, y [m] in ``map``.
        radius: [m] points farther from the robot than this are left out (as
            ``dwa._local_points``).
        c, s: ``np.cos`` and ``np.sin`` of the yaw (``dwa.point_gaps``' rounding).
        cx, cy, hx, hy: the footprint box's centre x, y [m] in ``base_footprint``, its half
            length and half width [m].

    Returns:
        ``(times, th, px, py, gap)``: (T,) ``horizon * arange(1, n + 1) / n`` [s]; (W, T) yaws
        ``th0 + ws * times`` [rad]; (L,) x and (L,) y [m] of the points within ``radius``; and
        the least Chebyshev gap [m] between the footprint at the robot's pose and those points
        (``inf`` without), the arithmetic of ``dwa.point_gaps``.
    """
    times = np.empty(n)
    for t in range(n):
        times[t] = horizon * (t + 1) / n
    nw = ws.shape[0]
    th = np.empty((nw, n))
    for j in range(nw):
        for t in range(n):
            th[j, t] = th0 + ws[j] * times[t]
    r2 = radius * radius
    m = obstacles.shape[0]
    keep = np.empty(m, dtype=np.int64)
    n_keep = 0
    for i in range(m):
        dx = obstacles[i, 0] - x0
        dy = obstacles[i, 1] - y0
        if dx * dx + dy * dy <= r2:
            keep[n_keep] = i
            n_keep += 1
    px = np.empty(n_keep)
    py = np.empty(n_keep)
    bx = x0 + c * cx - s * cy
    by = y0 + s * cx + c * cy
    gap = math.inf
    for i in range(n_keep):
        px[i] = obstacles[keep[i], 0]
        py[i] = obstacles[keep[i], 1]
        dx = px[i] - bx
        dy = py[i] - by
        gap = min(gap, max(abs(c * dx + s * dy) - hx, abs(c * dy - s * dx) - hy))
    return times, th, px, py, gap


@njit(cache=True, nogil=True)
def lookahead(path_x, path_y, rx, ry, dist, i0):
    """The lookahead point ``dist`` [m] along the path from its point ``i0`` (the one nearest
    the robot at ``rx, ry``), and the path's heading there.

    The length along the path is summed segment by segment in order (``np.cumsum``'s
    arithmetic) up to the first point at least ``dist`` along (``np.searchsorted``'s); the point
    is interpolated on the segment before it.  From the path's last point (or beyond it) the
    lookahead point is that last point, with the last segment's heading (with a single point,
    the heading from the robot to it).

    Args:
        path_x, path_y: (N,) the path [m] in ``map``; rx, ry: the robot's position [m].
        dist: the lookahead distance [m]; i0: the index of the path point nearest the robot.

    Returns:
        ``(carrot_x, carrot_y, ty, tx, has_tangent)``: the point [m] in ``map``, and the
        arguments of ``atan2`` for the path's heading there (``has_tangent`` False: heading 0).
    """
    n = path_x.shape[0]
    if n - i0 == 1:
        dx = path_x[i0] - rx
        dy = path_y[i0] - ry
        if n > 1:
            return path_x[i0], path_y[i0], path_y[n - 1] - path_y[n - 2], \
                path_x[n - 1] - path_x[n - 2], True
        return path_x[i0], path_y[i0], dy, dx, math.hypot(dx, dy) > 1e-6
    # s: the cumulative length along path[i0:], summed in order as np.cumsum; the first s >= dist
    # is np.searchsorted's (side left) answer
    s_prev = 0.0
    s_k = 0.0
    k = 0
    if not 0.0 >= dist:
        k = n - i0
        for q in range(1, n - i0):
            s_prev = s_k
            s_k = s_k + math.hypot(path_x[i0 + q] - path_x[i0 + q - 1],
                                   path_y[i0 + q] - path_y[i0 + q - 1])
            if s_k >= dist:
                k = q
                break
    if k >= n - i0:
        return path_x[n - 1], path_y[n - 1], path_y[n - 1] - path_y[n - 2], \
            path_x[n - 1] - path_x[n - 2], True
    if k == 0:  # dist <= 0: the first segment
        k = 1
        s_prev = 0.0
        s_k = math.hypot(path_x[i0 + 1] - path_x[i0], path_y[i0 + 1] - path_y[i0])
    a = i0 + k - 1
    f = (dist - s_prev) / max(s_k - s_prev, 1e-9)
    return (path_x[a] + f * (path_x[a + 1] - path_x[a]),
            path_y[a] + f * (path_y[a + 1] - path_y[a]),
            path_y[a + 1] - path_y[a], path_x[a + 1] - path_x[a], True)


@njit(cache=True, nogil=True)
def rollouts_and_bounds(x0, y0, s0, c0, vs, ws, times, cos_th, sin_th, cx, cy, radius, dt_check,
                        need, px, py, grid, r_out, r_in, path_x, path_y, dist):
    """The rollouts, their gap bounds, and where they aim: :func:`rollout_boxes`,
    :func:`gap_bounds` and :func:`lookahead` in one call.

    Args:
        x0, y0, s0, c0, vs, ws, times, cos_th, sin_th, cx, cy, radius, dt_check, need: as
            :func:`rollout_boxes` (``s0``, ``c0``: ``math.sin`` and ``math.cos``).
        px, py, grid, r_out, r_in: as :func:`gap_bounds` (L, the points within reach, may be 0).
        path_x, path_y: (N,) the local path [m] in ``map``, N > 0; dist: the lookahead
            distance [m] (:func:`lookahead`).

    Returns:
        ``(x, y, bx, by, need_s, lower, upper_min, est_min, unsure, to_path, i0, carrot_x,
        carrot_y, ty, tx, has_tangent, end_dx, end_dy)``: those of :func:`rollout_boxes` (but the
        box bounds) and :func:`gap_bounds` (``inf`` and no unsure pose without points); (N,)
        each path point's distance [m] to the robot and the index of the nearest (the first of
        equals); those of :func:`lookahead`; and (S,) the offset [m] of the carrot from each
        rollout's end, for ``np.arctan2``.
    """
    nw = ws.shape[0]
    straight = np.empty(nw, dtype=np.bool_)
    ws_safe = np.empty(nw)
    for j in range(nw):
        straight[j] = abs(ws[j]) < 1e-6
        ws_safe[j] = 1.0 if straight[j] else ws[j]
    x, y, bx, by, box_bounds, need_s = rollout_boxes(
        x0, y0, s0, c0, vs, ws, ws_safe, straight, times, cos_th, sin_th, cx, cy, radius,
        dt_check, need)
    ns, nt = bx.shape
    if px.shape[0] == 0:
        lower = np.full((ns, nt), math.inf)
        upper_min = np.full(ns, math.inf)
        est_min = np.full(ns, math.inf)
        unsure = np.zeros((ns, nt), dtype=np.bool_)
    else:
        lower, upper_min, est_min, unsure = gap_bounds(bx, by, box_bounds, px, py, grid, r_out,
                                                       r_in, need_s)
    npath = path_x.shape[0]
    to_path = np.empty(npath)
    i0 = 0
    for i in range(npath):
        to_path[i] = math.hypot(path_x[i] - x0, path_y[i] - y0)
        if to_path[i] < to_path[i0]:
            i0 = i
    carrot_x, carrot_y, ty, tx, has_tangent = lookahead(path_x, path_y, x0, y0, dist, i0)
    end_dx = np.empty(ns)
    end_dy = np.empty(ns)
    for k in range(ns):
        end_dx[k] = carrot_x - x[k, nt - 1]
        end_dy[k] = carrot_y - y[k, nt - 1]
    return (x, y, bx, by, need_s, lower, upper_min, est_min, unsure, to_path, i0, carrot_x,
            carrot_y, ty, tx, has_tangent, end_dx, end_dy)


@njit(cache=True, nogil=True)
def choose(x, y, aim_end, th, vs, ws, rx, ry, carrot_x, carrot_y, tangent, path_x, path_y,
           to_path, i0, est_min, upper_min, need, max_vel_x, influence, scales, lower, unsure, bx,
           by, cos_th, sin_th, px, py, hx, hy):
    """The admissible rollout of least cost: :func:`score_rollouts`, then
    :func:`first_admissible` and :func:`rollout_min_gap` on the candidates (arguments as
    theirs; ``th`` (W, T) the rollouts' yaws [rad]).

    Returns:
        ``(cost, best, min_gap)``: (S,) the weighted costs, the chosen rollout (-1: none is
        admissible) and the least gap [m] along it (``inf`` when none).
    """
    nt = th.shape[1]
    th_end = np.empty(th.shape[0])
    for j in range(th.shape[0]):
        th_end[j] = th[j, nt - 1]
    cost, order = score_rollouts(x, y, aim_end, th_end, vs, ws, rx, ry, carrot_x, carrot_y,
                                 tangent, path_x, path_y, to_path, i0, est_min, upper_min, need,
                                 max_vel_x, influence, scales)
    best = first_admissible(order, unsure, need, bx, by, cos_th, sin_th, px, py, hx, hy)
    min_gap = math.inf
    if best >= 0:
        min_gap = rollout_min_gap(best, lower, unsure, bx, by, cos_th, sin_th, px, py, hx, hy)
    return cost, best, min_gap
