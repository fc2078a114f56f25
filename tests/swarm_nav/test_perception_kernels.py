"""The compiled perception gives bit-identical answers to the numpy and scipy code it replaced.

The reference below is the implementation of ``swarm_nav.perception`` before the speed-up (commit
dee4c65): single linkage from a k-d tree's pairs and min-label propagation, centroids by
``np.add.at``, velocities from a ``hypot`` matrix and ``argmin``. The new code must reproduce
its labels, cluster numbering, centres, velocities, points and arrays exactly (``==``, NaN equal
to NaN, same dtypes) on many random scenes: crowds of robot outlines seen from a viewer, isolated
points, chains of points exactly ``link`` apart, duplicates, empty and single-point inputs.
"""

import math

import numpy as np
import pytest
from scipy.spatial import cKDTree

from swarm_nav import perception_kernels
from swarm_nav.config import PerceptionConfig
from swarm_nav.costmap import Costmap
from swarm_nav.perception import (
    CENTRE_DEPTH,
    RobotTracker,
    SeenRobot,
    dynamic_points,
)
from tests.swarm_nav.helpers import footprint_polygon
from tests.swarm_nav.perception_steps import (
    centres_of,
    cluster_centres,
    cluster_points,
    estimate_velocities,
    perceive_robots,
    robot_centres,
    seen_arrays_of,
)

PCFG = PerceptionConfig()


# ---------------------------------------------------------------- the reference (before)
def ref_dynamic_points(points, costmap, tolerance):
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return pts
    return pts[costmap.distance_at(pts) > tolerance]


def ref_cluster_points(points, link=0.2):
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    m = len(pts)
    if m <= 1:
        return np.zeros(m, dtype=int), m
    pairs = cKDTree(pts).query_pairs(link, output_type="ndarray")
    own = np.arange(m)
    src = np.concatenate((own, pairs[:, 0], pairs[:, 1]))
    dst = np.concatenate((own, pairs[:, 1], pairs[:, 0]))
    order = np.argsort(src, kind="stable")
    dst = dst[order]
    first = np.searchsorted(src[order], own)
    labels = own
    while True:
        new = np.minimum.reduceat(labels[dst], first)
        new = new[new]
        if np.array_equal(new, labels):
            break
        labels = new
    _, labels = np.unique(labels, return_inverse=True)
    return labels.reshape(-1), int(labels.max()) + 1


def refcentres_of(pts, labels, n, viewer_xy, depth):
    if n == 0:
        return np.zeros((0, 2))
    sums = np.zeros((n, 2))
    np.add.at(sums, labels, pts)
    centroids = sums / np.bincount(labels, minlength=n)[:, None]
    away = centroids - np.asarray(viewer_xy, dtype=float)
    norm = np.hypot(away[:, 0], away[:, 1])[:, None]
    return centroids + depth * away / np.maximum(norm, 1e-9)


def ref_estimate_velocities(centres, earlier, dt, gate=0.3, max_speed=0.5):
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    e = np.asarray(earlier, dtype=float).reshape(-1, 2)
    out = np.full(c.shape, np.nan)
    if len(c) == 0 or len(e) == 0 or dt <= 0:
        return out
    d = np.hypot(c[:, None, 0] - e[None, :, 0], c[:, None, 1] - e[None, :, 1])
    j = np.argmin(d, axis=1)
    ok = d[np.arange(len(c)), j] <= gate + max_speed * dt
    out[ok] = (c[ok] - e[j[ok]]) / dt
    return out


def ref_perceive_robots(dyn_points, viewer_xy, earlier=None, dt=0.0):
    pts = np.asarray(dyn_points, dtype=float).reshape(-1, 2)
    labels, n = ref_cluster_points(pts)
    if n == 0:
        return []
    centres = refcentres_of(pts, labels, n, viewer_xy, CENTRE_DEPTH)
    if earlier is None:
        vel = np.full((n, 2), np.nan)
    else:
        vel = ref_estimate_velocities(centres, earlier, dt)
    return [SeenRobot(centres[k], pts[labels == k], vel[k]) for k in range(n)]


class RefTracker:
    def __init__(self, cfg):
        self.cfg = cfg
        self._history = []

    def update(self, dyn_points, viewer_xy, now):
        cfg = self.cfg
        self._history = [(t, c) for t, c in self._history
                         if now - t <= cfg.velocity_history and t < now]
        old = [(t, c) for t, c in self._history if now - t >= cfg.velocity_min_baseline]
        earlier, dt = (None, 0.0)
        if old:
            t_old, earlier = min(old, key=lambda tc: abs(now - tc[0] - cfg.velocity_baseline))
            dt = now - t_old
        robots = ref_perceive_robots(dyn_points, viewer_xy, earlier, dt)
        self._history.append((now, robot_centres(robots)))
        return robots


def ref_seen_arrays(robots):
    if not robots:
        z2, zi = np.zeros((0, 2)), np.zeros(0, dtype=int)
        return (z2, z2, np.zeros(0, dtype=bool), np.zeros(0), z2, zi, zi, zi)
    velocity = np.array([r.velocity for r in robots], dtype=float)
    known = np.isfinite(velocity).all(axis=1)
    speed = np.where(known, np.hypot(velocity[:, 0], velocity[:, 1]), 0.0)
    sizes = np.array([len(r.points) for r in robots], dtype=int)
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(int)
    return (robot_centres(robots), velocity, known, speed, np.vstack([r.points for r in robots]),
            np.repeat(np.arange(len(robots)), sizes), starts, sizes)


# ---------------------------------------------------------------- comparisons
def same(a, b):
    """Equal arrays to the bit: shapes, dtypes, values (NaN equal to NaN)."""
    a, b = np.asarray(a), np.asarray(b)
    return (a.shape == b.shape and a.dtype == b.dtype
            and np.array_equal(a, b, equal_nan=a.dtype.kind == "f"))


def same_robots(new, old):
    assert len(new) == len(old)
    for r, q in zip(new, old, strict=True):
        assert same(r.centre, q.centre)
        assert same(r.points, q.points)
        assert same(r.velocity, q.velocity)


def same_seen(seen, ref):
    names = ("centres", "velocity", "known", "speed", "points", "owner", "starts", "sizes")
    for name, want in zip(names, ref, strict=True):
        assert same(getattr(seen, name), want), name


# ---------------------------------------------------------------- random scenes
def outline_points(rng, centre, viewer, noise=0.01):
    """The lidar's view of a waffle at ``centre``: its polygon's edges, sampled, the side nearer
    the viewer kept, with a little noise."""
    poly = footprint_polygon(np.array([*centre, rng.uniform(-math.pi, math.pi)]))
    edges = np.vstack([poly[k] + np.outer(np.linspace(0, 1, 8, endpoint=False),
                                          poly[(k + 1) % len(poly)] - poly[k])
                       for k in range(len(poly))])
    near = np.hypot(*(edges - viewer).T) <= np.hypot(*(np.asarray(centre) - viewer)) + 0.02
    return edges[near] + noise * rng.standard_normal((int(near.sum()), 2))


def scene(rng):
    """(M, 2) dynamic points of a random scene and the viewer's x, y."""
    viewer = rng.uniform(-5, 5, 2)
    parts = [np.zeros((0, 2))]
    for _ in range(rng.integers(0, 9)):
        parts.append(outline_points(rng, viewer + rng.uniform(-3, 3, 2), viewer))
    parts.append(viewer + rng.uniform(-3, 3, (rng.integers(0, 12), 2)))   # isolated points
    if rng.random() < 0.3:   # a chain of points exactly one link (or its float neighbours) apart
        start = viewer + rng.uniform(-3, 3, 2)
        step = np.nextafter(0.2, [0.0, 1.0, 0.2][rng.integers(0, 3)])
        along = np.arange(rng.integers(2, 8)) * step
        if rng.random() < 0.5:
            parts.append(start + np.column_stack((along, np.zeros_like(along))))
        else:
            parts.append(start + np.column_stack((np.zeros_like(along), along)))
    if rng.random() < 0.2 and sum(map(len, parts)):   # duplicated points
        allp = np.vstack(parts)
        parts.append(allp[rng.integers(0, len(allp), 3)])
    pts = np.vstack(parts)
    return pts[rng.permutation(len(pts))] if rng.random() < 0.5 else pts, viewer


SEEDS = range(300)


@pytest.mark.parametrize("seed", SEEDS[:100])
def test_cluster_points_as_before(seed):
    rng = np.random.default_rng(seed)
    pts, _ = scene(rng)
    for link in (0.2, 0.1, 0.35):
        labels, n = cluster_points(pts, link)
        want, n_want = ref_cluster_points(pts, link)
        assert n == n_want and type(n) is type(n_want)
        assert same(labels, want)


def test_cluster_points_at_the_link_distance():
    # coordinates whose squared distance is exactly link * link, one ulp above and one below
    for link in (0.2, 0.1, 0.25, 0.3):
        for dx, dy in ((link, 0.0), (0.0, link), (0.6 * link, 0.8 * link),
                       (np.nextafter(link, 1), 0.0), (np.nextafter(link, 0), 0.0)):
            for x0, y0 in ((0.0, 0.0), (1.3, -2.7), (-7.1, 4.05)):
                pts = np.array([[x0, y0], [x0 + dx, y0 + dy], [x0 + 5, y0]])
                labels, n = cluster_points(pts, link)
                want, n_want = ref_cluster_points(pts, link)
                assert n == n_want and same(labels, want), (link, dx, dy, x0, y0)


def test_cluster_points_on_big_clouds_near_the_boundary():
    # hundreds of points on a grid of pitch ``link`` (many pairs exactly at the boundary), through
    # the k-d tree's inner nodes (more than its 16 points a leaf)
    rng = np.random.default_rng(7)
    for link in (0.2, 0.05):
        for _ in range(10):
            g = np.argwhere(rng.random((20, 20)) < 0.5) * link + rng.uniform(-9, 9, 2)
            g = g[rng.permutation(len(g))]
            labels, n = cluster_points(g, link)
            want, n_want = ref_cluster_points(g, link)
            assert n == n_want and same(labels, want)


def test_cluster_points_small_and_bad_inputs():
    for pts in (np.zeros((0, 2)), np.array([[1.0, 2.0]]), np.array([[np.nan, 0.0]]),
                np.array([[0.0, 0.0], [0.0, 0.0]]), [0.5, 0.5, 0.6, 0.5], []):
        labels, n = cluster_points(pts)
        want, n_want = ref_cluster_points(pts)
        assert n == n_want and same(labels, want)
    for bad in (np.array([[0.0, 0.0], [np.nan, 0.0]]), np.array([[0.0, np.inf], [0.0, 0.0]])):
        with pytest.raises(ValueError, match="must be finite"):
            ref_cluster_points(bad)
        with pytest.raises(ValueError, match="must be finite"):
            cluster_points(bad)
        with pytest.raises(ValueError, match="must be finite"):
            perceive_robots(bad, [0.0, 0.0])


@pytest.mark.parametrize("seed", SEEDS[:100])
def test_centres_as_before(seed):
    rng = np.random.default_rng(seed)
    pts, viewer = scene(rng)
    labels, n = ref_cluster_points(pts)
    for depth in (CENTRE_DEPTH, 0.25):
        assert same(centres_of(pts, labels, n, viewer, depth),
                    refcentres_of(pts, labels, n, viewer, depth))
        assert same(cluster_centres(pts, viewer, 0.2, depth),
                    refcentres_of(pts, labels, n, viewer, depth))
    if n:   # a viewer on a centroid (norm below 1e-9) and a NaN viewer
        c = refcentres_of(pts, labels, n, viewer, 0.0)[0]
        for v in (c, [np.nan, 0.0]):
            assert same(centres_of(pts, labels, n, v, 0.1),
                        refcentres_of(pts, labels, n, v, 0.1))


@pytest.mark.parametrize("seed", SEEDS[:100])
def test_estimate_velocities_as_before(seed):
    rng = np.random.default_rng(seed)
    c = rng.uniform(-3, 3, (rng.integers(0, 10), 2))
    e = np.vstack((c[: rng.integers(0, len(c) + 1)] + rng.normal(0, 0.3, (1, 2)),
                   rng.uniform(-3, 3, (rng.integers(0, 6), 2))))
    e = e[rng.permutation(len(e))]
    if len(e) > 1 and rng.random() < 0.3:
        e[1] = e[0]   # two equally near
    if len(e) and rng.random() < 0.2:
        e[rng.integers(0, len(e))] = np.nan
    for dt in (0.0, -0.1, 0.4, 1.0, 1.3):
        for gate, max_speed in ((0.3, 0.5), (0.0, 0.2), (1.0, 0.0)):
            assert same(estimate_velocities(c, e, dt, gate, max_speed),
                        ref_estimate_velocities(c, e, dt, gate, max_speed))


@pytest.mark.parametrize("seed", SEEDS)
def test_perceive_robots_as_before(seed):
    rng = np.random.default_rng(seed)
    pts, viewer = scene(rng)
    earlier = None
    if rng.random() < 0.7:
        earlier = np.vstack((robot_centres(ref_perceive_robots(pts, viewer))
                             + rng.normal(0, 0.1, (1, 2)), rng.uniform(-5, 5, (2, 2))))
    dt = float(rng.choice([0.0, 0.4, 1.0]))
    new = perceive_robots(pts, viewer, earlier, dt)
    old = ref_perceive_robots(pts, viewer, earlier, dt)
    same_robots(new, old)
    same_seen(seen_arrays_of(new), ref_seen_arrays(old))


def test_tracker_and_its_arrays_as_before():
    # robots driving past a viewer for 30 s, scans at 5 Hz with jitter and gaps
    rng = np.random.default_rng(11)
    for _ in range(5):
        tracker, ref = RobotTracker(PCFG), RefTracker(PCFG)
        viewer = rng.uniform(-2, 2, 2)
        starts = viewer + rng.uniform(-3, 3, (rng.integers(0, 7), 2))
        vels = rng.uniform(-0.5, 0.5, starts.shape)
        t = 0.0
        for _step in range(150):
            t += float(rng.choice([0.2, 0.2, 0.19, 0.21, 0.6, 2.0], p=[.5, .2, .1, .1, .07, .03]))
            parts = [outline_points(rng, s + v * t, viewer) for s, v in zip(starts, vels,
                                                                             strict=True)]
            pts = np.vstack([np.zeros((0, 2)), *parts])
            if rng.random() < 0.1:
                pts = pts[: len(pts) // 2]
            robots, seen = tracker.update(pts, viewer, t)
            old = ref.update(pts, viewer, t)
            same_robots(robots, old)
            same_seen(seen, ref_seen_arrays(old))
            same_seen(seen_arrays_of(robots), ref_seen_arrays(old))
        assert len(tracker._history) == len(ref._history)
        for (t1, c1), (t2, c2) in zip(tracker._history, ref._history, strict=True):
            assert t1 == t2 and same(c1, c2)


def test_dynamic_points_as_before(costmap):
    rng = np.random.default_rng(5)
    h, w = costmap.height, costmap.width
    lo = costmap.origin[:2] - 1.0
    hi = costmap.origin[:2] + costmap.resolution * np.array([w, h]) + 1.0
    for _ in range(50):
        pts = rng.uniform(lo, hi, (rng.integers(0, 400), 2))
        # points on cell borders, some exactly
        edge = costmap.origin[:2] + costmap.resolution * rng.integers(-2, max(h, w), (20, 2))
        pts = np.vstack((pts, edge, np.nextafter(edge, -np.inf)))
        for tol in (0.0, 0.1, PCFG.static_point_tolerance):
            assert same(dynamic_points(pts, costmap, tol), ref_dynamic_points(pts, costmap, tol))
    assert same(dynamic_points(np.zeros((0, 2)), costmap, 0.1),
                ref_dynamic_points(np.zeros((0, 2)), costmap, 0.1))
    # a float64 distance field, and a non-contiguous input
    c64 = Costmap(costmap.costs, costmap.resolution, costmap.origin,
                  costmap.obstacle_distance.astype(float))
    pts = np.repeat(rng.uniform(lo, hi, (300, 2)), 2, axis=1)[:, ::2]
    assert same(dynamic_points(pts, c64, 0.1), ref_dynamic_points(pts, c64, 0.1))


def test_dynamic_points_of_huge_coordinates_take_numpy_s_path(costmap):
    pts = np.array([[1e30, 0.0], [0.0, 0.0]])
    assert perception_kernels.dynamic_mask(pts, 0.0, 0.0, 0.05, costmap.obstacle_distance,
                                           0.1)[1] is False
    with np.errstate(invalid="ignore"):   # numpy's cast of 2e31 to int warns
        assert same(dynamic_points(pts, costmap, 0.1), ref_dynamic_points(pts, costmap, 0.1))


# ---------------------------------------------------------------- the navigator's on_scan pieces
def ref_finite_rows(points):
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    return pts[np.all(np.isfinite(pts), axis=1)]


def ref_moving_points(seen, moving_speed):
    moving = seen.known & (seen.speed > moving_speed)
    rows = np.flatnonzero(moving[seen.owner])
    twice = np.concatenate((rows, rows))
    order = np.argsort(seen.owner[twice], kind="stable")
    idx = twice[order]
    later = order >= len(rows)
    return seen.points[idx], seen.velocity[seen.owner[idx]], later


@pytest.mark.parametrize("seed", SEEDS[:50])
def test_finite_rows_as_before(seed):
    rng = np.random.default_rng(seed)
    pts = rng.uniform(-5, 5, (rng.integers(0, 300), 2))
    bad = rng.random(pts.shape) < 0.05
    pts[bad] = rng.choice([np.nan, np.inf, -np.inf], int(bad.sum()))
    assert same(perception_kernels.finite_rows(pts), ref_finite_rows(pts))


@pytest.mark.parametrize("seed", SEEDS[:100])
def test_moving_points_as_before(seed):
    rng = np.random.default_rng(seed)
    pts, viewer = scene(rng)
    earlier = np.vstack((robot_centres(ref_perceive_robots(pts, viewer))
                         + rng.normal(0, 0.15, (1, 2)), rng.uniform(-5, 5, (2, 2))))
    tracker = RobotTracker(PCFG)
    tracker._history = [(0.0, earlier)]
    _, seen = tracker.update(pts, viewer, 0.5)
    for speed in (0.0, 0.05, 0.2):
        moving = seen.known & (seen.speed > speed)
        got = perception_kernels.moving_points(seen.points, seen.starts, seen.sizes,
                                               seen.velocity, moving)
        for a, b in zip(got, ref_moving_points(seen, speed), strict=True):
            assert same(a, b)
