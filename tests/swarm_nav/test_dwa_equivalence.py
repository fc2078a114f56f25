"""The sped-up local planner gives bit-identical answers to the straightforward one it replaced.

The reference below is the implementation of ``swarm_nav.dwa`` before the speed-up (commit
7bf5e09): every rollout computes its own headings, the exact check compares every unsure pose
with every local point, the path critic compares every rollout end with the whole rest of the
path. The new code must reproduce its commands, costs, gaps and trajectories exactly (``==``, not
approximately) on many random scenes: crowds of robot outlines, walls, points inside the padding,
paths that bend back toward the robot.
"""

import math

import numpy as np
import pytest
from scipy import ndimage

from swarm_common.geometry import wrap_angle
from swarm_nav import dwa_kernels
from swarm_nav.config import DwaConfig
from swarm_nav.dwa import (
    _GRID,
    Command,
    Footprint,
    RobotState,
    _fallback,
    _local_points,
    dwa_command,
    dynamic_window,
    footprint_gaps,
    point_gaps,
)
from tests.swarm_nav.helpers import WAFFLE_FOOTPRINT, rollout

CFG = DwaConfig()
FP = Footprint.from_polygon(WAFFLE_FOOTPRINT)
DT = 0.1


# ---------------------------------------------------------------- the reference (before)
REF_BATCH = 40


def ref_lookahead_from(path, xy, dist, i0):
    """The reference's lookahead from a given nearest point ``i0`` (its own code after argmin)."""
    rest = path[i0:]
    if len(rest) == 1:
        d = rest[0] - xy
        heading = math.atan2(d[1], d[0]) if np.hypot(*d) > 1e-6 else 0.0
        if len(path) > 1:
            seg = path[-1] - path[-2]
            heading = math.atan2(seg[1], seg[0])
        return rest[0], heading
    seg = np.diff(rest, axis=0)
    s = np.concatenate(([0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))))
    k = int(np.searchsorted(s, dist))
    if k >= len(rest):
        return rest[-1], math.atan2(seg[-1, 1], seg[-1, 0])
    k = max(k, 1)
    f = (dist - s[k - 1]) / max(s[k] - s[k - 1], 1e-9)
    return rest[k - 1] + f * (rest[k] - rest[k - 1]), math.atan2(seg[k - 1, 1], seg[k - 1, 0])


def ref_lookahead(path, xy, dist):
    return ref_lookahead_from(path, xy, dist, int(np.argmin(np.hypot(*(path - xy).T))))


def ref_gaps(x, y, yaw, pts, footprint):
    cx, cy = footprint.centre
    hx, hy = footprint.half_size
    yaw = np.asarray(yaw, dtype=float)
    c, s = np.cos(yaw)[..., None], np.sin(yaw)[..., None]
    bx = np.asarray(x, dtype=float)[..., None] + c * cx - s * cy
    by = np.asarray(y, dtype=float)[..., None] + s * cx + c * cy
    dx = pts[:, 0] - bx
    dy = pts[:, 1] - by
    return np.maximum(np.abs(c * dx + s * dy) - hx, np.abs(c * dy - s * dx) - hy)


def ref_footprint_gaps(x, y, yaw, points, footprint):
    x = np.asarray(x, dtype=float)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return np.full(x.shape, np.inf)
    return ref_gaps(x, y, yaw, pts, footprint).min(axis=-1)


def ref_point_gaps(pose, points, footprint):
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return ref_gaps(pose[0], pose[1], pose[2], pts, footprint)


def ref_gap_bounds(x, y, th, pts, footprint):
    if len(pts) == 0:
        inf = np.full(x.shape, np.inf)
        return inf, inf, inf
    cx, cy = footprint.centre
    hx, hy = footprint.half_size
    r_out, r_in = math.hypot(hx, hy), min(hx, hy)
    c, s = np.cos(th), np.sin(th)
    bx = x + c * cx - s * cy
    by = y + s * cx + c * cy
    lo = np.array([min(bx.min(), pts[:, 0].min()), min(by.min(), pts[:, 1].min())]) - 2 * _GRID
    hi = np.array([max(bx.max(), pts[:, 0].max()), max(by.max(), pts[:, 1].max())]) + 2 * _GRID
    shape = np.ceil((hi - lo) / _GRID).astype(int) + 1
    free = np.ones((shape[1], shape[0]), dtype=bool)
    pc = ((pts - lo) / _GRID).astype(int)
    free[pc[:, 1], pc[:, 0]] = False
    dist = ndimage.distance_transform_edt(free) * _GRID
    d = dist[((by - lo[1]) / _GRID).astype(int), ((bx - lo[0]) / _GRID).astype(int)]
    err = _GRID * math.sqrt(2.0)
    return d - err - r_out, d + err - r_in, d - 0.5 * (r_in + r_out)


def ref_dwa_command(state, path, obstacles, cfg, *, footprint, dt):
    pose = np.asarray(state.pose, dtype=float).reshape(3)
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    v_lo, v_hi, w_lo, w_hi = dynamic_window(state, cfg, dt)
    vs = np.linspace(v_lo, v_hi, cfg.vx_samples) if v_hi > v_lo else np.array([v_lo])
    ws = np.linspace(w_lo, w_hi, cfg.vtheta_samples) if w_hi > w_lo else np.array([w_lo])
    if w_lo < 0.0 < w_hi and not np.any(ws == 0.0):
        ws = np.append(ws, 0.0)
    V, W = (a.ravel() for a in np.meshgrid(vs, ws, indexing="ij"))
    reach_v = max(abs(v_lo), abs(v_hi))
    reach_w = max(abs(w_lo), abs(w_hi))
    horizon = max(cfg.sim_time, dt + reach_v / abs(cfg.decel_lim_x))
    n = max(1, math.ceil(reach_v * horizon / cfg.sim_granularity),
            math.ceil(reach_w * horizon / cfg.angular_sim_granularity))
    times = horizon * np.arange(1, n + 1) / n
    x, y, th = rollout(pose, V, W, times)
    local = _local_points(obstacles, pose, reach_v * horizon + footprint.radius
                          + cfg.footprint_padding + 2 * _GRID)
    gap0 = (math.inf if len(local) == 0 else
            float(ref_footprint_gaps(pose[:1], pose[1:2], pose[2:3], local, footprint)[0]))
    need = min(cfg.footprint_padding, gap0)
    step = (np.abs(V) + np.abs(W) * footprint.radius) * (horizon / n)
    need_s = (need + 0.5 * step)[:, None]
    lower, upper, est = ref_gap_bounds(x, y, th, local, footprint)
    sure_bad = (upper < need_s).any(axis=1)
    unsure = lower < need_s
    moving = (np.abs(V) > 1e-9) | (np.abs(W) > 1e-9)
    carrot, tangent = ref_lookahead(path, pose[:2], cfg.lookahead_dist)
    ex, ey, eth = x[:, -1], y[:, -1], th[:, -1]
    to_carrot = carrot - np.column_stack((ex, ey))
    goal_dist = np.hypot(to_carrot[:, 0], to_carrot[:, 1])
    i0 = int(np.argmin(np.hypot(*(path - pose[:2]).T)))
    rest = path[i0:]
    path_dist = np.sqrt(((ex[:, None] - rest[None, :, 0]) ** 2
                         + (ey[:, None] - rest[None, :, 1]) ** 2).min(axis=1))
    aim = np.where(goal_dist > 0.15, np.arctan2(to_carrot[:, 1], to_carrot[:, 0]), tangent)
    align = np.abs(wrap_angle(eth - aim))
    infl = cfg.obstacle_influence
    obst = np.clip((infl - est.min(axis=1)) / infl, 0.0, 1.0) ** 2
    speed = (cfg.max_vel_x - V) / cfg.max_vel_x
    cost = (cfg.path_dist_scale * path_dist + cfg.goal_dist_scale * goal_dist
            + cfg.path_align_scale * align + cfg.obstacle_scale * obst + cfg.speed_scale * speed)
    order = np.flatnonzero(moving & ~sure_bad)
    order = order[np.argsort(cost[order], kind="stable")]
    for k in range(0, len(order), REF_BATCH):
        idx = order[k:k + REF_BATCH]
        gaps = np.where(unsure[idx], np.inf, lower[idx])
        mask = unsure[idx]
        if mask.any():
            gaps[mask] = ref_footprint_gaps(x[idx][mask], y[idx][mask], th[idx][mask], local,
                                            footprint)
        ok = (gaps >= need_s[idx]).all(axis=1)
        if ok.any():
            j = int(np.argmax(ok))
            best = int(idx[j])
            traj = np.column_stack((x[best], y[best], wrap_angle(th[best])))
            return Command(float(V[best]), float(W[best]), True, float(cost[best]),
                           float(gaps[j].min()), traj)
    return _fallback(pose, carrot, tangent, local, footprint, cfg, (w_lo, w_hi))


# ---------------------------------------------------------------- random scenes
def robot_outline(rng, centre, n=14):
    """Scan-like points on the near side of another robot's box."""
    yaw = rng.uniform(-math.pi, math.pi)
    s = rng.uniform(-1.0, 1.0, size=n)
    local = np.column_stack((np.where(s > 0, 0.069, -0.197), 0.133 * s))
    c, si = math.cos(yaw), math.sin(yaw)
    return centre + local @ np.array([[c, si], [-si, c]])


def random_scene(rng):
    pose = np.array([*rng.uniform(-2.0, 2.0, size=2), rng.uniform(-math.pi, math.pi)])
    v = float(rng.choice([0.0, 0.26, rng.uniform(-0.05, 0.3)]))
    w = float(rng.choice([0.0, rng.uniform(-1.2, 1.2)]))
    parts = []
    for _ in range(rng.integers(0, 8)):  # other robots around, some very near
        r = rng.uniform(0.25, 1.2)
        a = rng.uniform(-math.pi, math.pi)
        parts.append(robot_outline(rng, pose[:2] + r * np.array([math.cos(a), math.sin(a)])))
    if rng.random() < 0.5:  # a wall
        a = rng.uniform(-math.pi, math.pi)
        d = rng.uniform(0.15, 1.0)
        normal = np.array([math.cos(a), math.sin(a)])
        s = np.arange(-1.5, 1.5, 0.02)[:, None]
        parts.append(pose[:2] + d * normal + s * np.array([-normal[1], normal[0]]))
    parts.append(pose[:2] + rng.uniform(-3.0, 3.0, size=(rng.integers(0, 200), 2)))  # clutter
    obstacles = np.vstack(parts) if parts else np.zeros((0, 2))
    heading = pose[2] + rng.uniform(-math.pi, math.pi)
    bend = rng.uniform(-2.5, 2.5)  # [rad/m]: up to paths that bend back toward the robot
    s = np.arange(0.0, rng.uniform(0.05, 3.0), 0.05)
    ang = heading + bend * s
    path = pose[:2] + rng.normal(0.0, 0.1, size=2) + np.column_stack(
        (np.cumsum(0.05 * np.cos(ang)), np.cumsum(0.05 * np.sin(ang))))
    return RobotState(pose, v, w), path, obstacles


def assert_same_command(a: Command, b: Command):
    assert (a.v, a.w, a.ok, a.cost, a.min_gap) == (b.v, b.w, b.ok, b.cost, b.min_gap)
    if a.trajectory is None:
        assert b.trajectory is None
    else:
        assert a.trajectory.shape == b.trajectory.shape
        assert np.array_equal(a.trajectory, b.trajectory)


@pytest.mark.parametrize("seed", range(4))
def test_dwa_command_equals_the_reference_on_random_scenes(seed):
    rng = np.random.default_rng(seed)
    outcomes = {"ok": 0, "stuck": 0}
    for _ in range(150):
        state, path, obstacles = random_scene(rng)
        got = dwa_command(state, path, obstacles, CFG, footprint=FP, dt=DT)
        want = ref_dwa_command(state, path, obstacles, CFG, footprint=FP, dt=DT)
        assert_same_command(got, want)
        outcomes["ok" if want.ok else "stuck"] += 1
    assert outcomes["ok"] >= 50 and outcomes["stuck"] >= 1  # both branches were exercised


@pytest.mark.parametrize("cfg", [
    DwaConfig(vx_samples=1, vtheta_samples=1),
    DwaConfig(vx_samples=7, vtheta_samples=4, footprint_padding=0.0),
    DwaConfig(min_vel_x=-0.1, vtheta_samples=9),
])
def test_dwa_command_equals_the_reference_with_other_settings(cfg):
    rng = np.random.default_rng(11)
    for _ in range(60):
        state, path, obstacles = random_scene(rng)
        assert_same_command(dwa_command(state, path, obstacles, cfg, footprint=FP, dt=DT),
                            ref_dwa_command(state, path, obstacles, cfg, footprint=FP, dt=DT))


@pytest.mark.parametrize("seed", range(3))
def test_gap_functions_equal_the_reference(seed):
    rng = np.random.default_rng(100 + seed)
    fp = Footprint(-0.3, 0.1, -0.12, 0.2)  # off-centre in both axes
    for footprint in (FP, fp):
        for _ in range(50):
            pose = rng.uniform([-1, -1, -4], [1, 1, 4])
            pts = rng.uniform(-1.0, 1.0, size=(rng.integers(0, 60), 2))
            assert np.array_equal(point_gaps(pose, pts, footprint),
                                  ref_point_gaps(pose, pts, footprint))
            poses = rng.uniform([-1, -1, -4], [1, 1, 4], size=(rng.integers(1, 30), 3))
            assert np.array_equal(
                footprint_gaps(poses[:, 0], poses[:, 1], poses[:, 2], pts, footprint),
                ref_footprint_gaps(poses[:, 0], poses[:, 1], poses[:, 2], pts, footprint))


@pytest.mark.parametrize("seed", range(3))
def test_compiled_rollouts_equal_rollout_per_pair(seed):
    """The compiled shared-heading rollouts and box centres are those of rollout() for every
    (v, w) pair, bit for bit."""
    rng = np.random.default_rng(200 + seed)
    cx, cy = FP.centre
    for _ in range(30):
        pose = rng.uniform([-5, -5, -4], [5, 5, 4])
        vs = np.sort(rng.uniform(-0.1, 0.3, size=rng.integers(1, 8)))
        ws = np.concatenate((rng.uniform(-1.0, 1.0, size=rng.integers(1, 8)), [0.0, 5e-7]))
        times = 1.7 * np.arange(1, 18) / 17
        th_w = pose[2] + ws[:, None] * times[None, :]
        straight = np.abs(ws) < 1e-6
        x, y, bx, by, bounds, need_s = dwa_kernels.rollout_boxes(
            pose[0], pose[1], math.sin(pose[2]), math.cos(pose[2]), vs, ws,
            np.where(straight, 1.0, ws), straight, times, np.cos(th_w), np.sin(th_w), cx, cy,
            FP.radius, 0.1, 0.05)
        V, W = np.repeat(vs, len(ws)), np.tile(ws, len(vs))
        rx, ry, th = rollout(pose, V, W, times)
        assert np.array_equal(need_s, 0.05 + 0.5 * ((np.abs(V) + np.abs(W) * FP.radius) * 0.1))
        assert np.array_equal(x, rx) and np.array_equal(y, ry)
        c, s = np.cos(th), np.sin(th)
        assert np.array_equal(bx, rx + c * cx - s * cy)
        assert np.array_equal(by, ry + s * cx + c * cy)
        assert np.array_equal(bounds, [bx.min(), bx.max(), by.min(), by.max()])


@pytest.mark.parametrize("seed", range(4))
def test_compiled_distance_transform_equals_scipy(seed):
    """The compiled exact distance transform gives scipy's distances to the last bit, on grids
    with one feature cell, a few, many, whole lines, and features at the borders."""
    rng = np.random.default_rng(300 + seed)
    for case in range(40):
        h, w = (int(v) for v in rng.integers(1, 70, size=2))
        n = [1, 3, int(rng.integers(1, h * w + 1))][case % 3]
        cells = rng.integers(0, h * w, size=n)
        if case % 7 == 0:  # a whole row and a whole column
            r, c = int(rng.integers(h)), int(rng.integers(w))
            cells = np.concatenate((cells, r * w + np.arange(w), np.arange(h) * w + c))
        rows, cols = (cells // w).astype(np.int64), (cells % w).astype(np.int64)
        free = np.ones((h, w), dtype=bool)
        free[rows, cols] = False
        ref = ndimage.distance_transform_edt(free)
        got = np.sqrt(dwa_kernels.squared_distance_grid(rows, cols, h, w))
        assert np.array_equal(got, ref), (h, w, n)


@pytest.mark.parametrize("seed", range(3))
def test_compiled_lookahead_equals_the_reference(seed):
    """The compiled lookahead (its sum stopped at the first point far enough) gives the
    reference's point and heading to the last bit: from every path point, with distances of 0,
    within the path, exactly at a point's distance along it, and beyond its end; on paths with
    repeated points and on single points."""
    rng = np.random.default_rng(400 + seed)
    for case in range(60):
        n = int(rng.integers(1, 40))
        path = np.cumsum(rng.normal(0.0, 0.05, size=(n, 2)), axis=0)
        if case % 5 == 0 and n > 2:
            path[n // 2] = path[n // 2 - 1]  # a zero-length segment
        xy = path[0] + rng.normal(0.0, 0.1, size=2)
        if case % 11 == 0:
            xy = path[0].copy()  # the robot on a single-point path: heading 0
        for i0 in range(n):
            seg = np.hypot(*np.diff(path[i0:], axis=0).T)
            along = np.cumsum(seg)
            dists = [0.0, 0.6, float(rng.uniform(0.0, 2.0))] + along[:2].tolist()
            for dist in dists:
                want_point, want_heading = ref_lookahead_from(path, xy, dist, i0)
                cx, cy, ty, tx, has = dwa_kernels.lookahead(
                    np.ascontiguousarray(path[:, 0]), np.ascontiguousarray(path[:, 1]),
                    float(xy[0]), float(xy[1]), dist, i0)
                assert (cx, cy) == (want_point[0], want_point[1]), (case, i0, dist)
                assert (math.atan2(ty, tx) if has else 0.0) == want_heading, (case, i0, dist)
