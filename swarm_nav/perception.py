"""What a robot sees of the other robots in its own scan: clusters, centres and velocities.

No communication: every robot knows the others only through its lidar. The scan points that the
static map does not explain (farther than ``static_point_tolerance`` from every lethal cell,
:func:`dynamic_points`) are grouped by single linkage (:func:`cluster_points`); each cluster is
one robot (:class:`SeenRobot`) whose centre lies a little behind its visible side
(:func:`cluster_centres`) and whose velocity comes from matching the centres to those of a scan
about ``velocity_baseline`` earlier (:func:`estimate_velocities`; :class:`RobotTracker` keeps
that short history). The holding pattern (:mod:`swarm_nav.holding`), the traffic rules
(:mod:`swarm_nav.traffic`) and the navigator (:mod:`swarm_nav.core`) use what is seen here.

Pure: numpy arrays in ``map`` and dataclasses, no ROS. Tests: tests/swarm_nav/test_perception.py.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from swarm_common.geometry import Points2D
from swarm_nav.config import PerceptionConfig
from swarm_nav.costmap import Costmap

CENTRE_DEPTH = 0.1  # [m] a robot's centre behind its visible side (about half a waffle's width)


def dynamic_points(points: Points2D, costmap: Costmap, tolerance: float) -> Points2D:
    """The scan points the static map does not explain (other robots, people, new objects).

    Args:
        points: (M, 2) scan end points x, y [m] in ``map``.
        costmap: the static costmap (its obstacle distance field).
        tolerance: a point nearer than this [m] to a lethal cell belongs to the map.

    Returns:
        (K, 2) the points farther than ``tolerance`` from every lethal cell (points outside the map
        count as static).
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return pts
    return pts[costmap.distance_at(pts) > tolerance]


@dataclass(frozen=True)
class SeenRobot:
    """Another robot as one scan shows it.

    Attributes:
        centre: (2,) estimated centre x, y [m] in ``map``.
        points: (n, 2) its scan points x, y [m] in ``map``.
        velocity: (2,) estimated velocity [m/s] in ``map`` from earlier scans; NaN when unknown.
    """

    centre: np.ndarray
    points: np.ndarray
    velocity: np.ndarray


def cluster_points(points: Points2D, link: float = 0.2) -> tuple[np.ndarray, int]:
    """Group points at most ``link`` [m] apart (single linkage); clusters are numbered in the
    order of their first point.

    Args:
        points: (M, 2) x, y [m].
        link: the linking distance [m].

    Returns:
        ``(labels, n)``: (M,) cluster index of each point, and the number of clusters.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    m = len(pts)
    if m <= 1:
        return np.zeros(m, dtype=int), m
    # the links (a k-d tree's pairs, both ways, and every point to itself) sorted by point
    pairs = cKDTree(pts).query_pairs(link, output_type="ndarray")
    own = np.arange(m)
    src = np.concatenate((own, pairs[:, 0], pairs[:, 1]))
    dst = np.concatenate((own, pairs[:, 1], pairs[:, 0]))
    order = np.argsort(src, kind="stable")
    dst = dst[order]
    first = np.searchsorted(src[order], own)  # each point's first link
    labels = own
    while True:  # min-label propagation with pointer jumping
        new = np.minimum.reduceat(labels[dst], first)
        new = new[new]
        if np.array_equal(new, labels):
            break
        labels = new
    _, labels = np.unique(labels, return_inverse=True)
    return labels.reshape(-1), int(labels.max()) + 1


def cluster_centres(points: Points2D, viewer_xy, link: float = 0.2,
                    depth: float = CENTRE_DEPTH) -> np.ndarray:
    """Estimated centres of the objects (robots) behind clusters of dynamic points.

    A lidar sees an object's near side, so each cluster's centroid is pushed ``depth`` [m] away
    from the viewer.

    Args:
        points: (M, 2) dynamic points x, y [m] in ``map``.
        viewer_xy: (2,) x, y [m] of the lidar (or robot) in ``map``.
        link: the clustering distance [m] (:func:`cluster_points`).
        depth: how far behind its visible side an object's centre lies [m].

    Returns:
        (K, 2) x, y [m] of the estimated centres, one per cluster.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    labels, n = cluster_points(pts, link)
    return _centres_of(pts, labels, n, viewer_xy, depth)


def _centres_of(pts: np.ndarray, labels: np.ndarray, n: int, viewer_xy, depth: float
                ) -> np.ndarray:
    """(n, 2) the centres of the clusters ``labels`` of ``pts`` (see :func:`cluster_centres`)."""
    if n == 0:
        return np.zeros((0, 2))
    sums = np.zeros((n, 2))
    np.add.at(sums, labels, pts)
    centroids = sums / np.bincount(labels, minlength=n)[:, None]
    away = centroids - np.asarray(viewer_xy, dtype=float)
    norm = np.hypot(away[:, 0], away[:, 1])[:, None]
    return centroids + depth * away / np.maximum(norm, 1e-9)


def estimate_velocities(centres: np.ndarray, earlier: np.ndarray, dt: float,
                        gate: float = 0.3, max_speed: float = 0.5) -> np.ndarray:
    """Velocities of clusters by matching each centre to the nearest centre of an earlier scan.

    Args:
        centres: (K, 2) centres x, y [m] now.
        earlier: (J, 2) centres [m] ``dt`` seconds earlier.
        dt: time [s] between the two (> 0).
        gate: a match may be at most ``gate + max_speed * dt`` [m] away.
        max_speed: the fastest a robot moves [m/s].

    Returns:
        (K, 2) velocities [m/s]; NaN where no earlier centre matched.
    """
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


def perceive_robots(dyn_points: Points2D, viewer_xy, earlier: np.ndarray | None = None,
                    dt: float = 0.0) -> list[SeenRobot]:
    """The other robots in a scan: clusters of dynamic points, their centres and velocities.

    Args:
        dyn_points: (M, 2) dynamic scan points x, y [m] in ``map`` (:func:`dynamic_points`).
        viewer_xy: (2,) the lidar's (or robot's) x, y [m].
        earlier: (J, 2) the centres [m] seen ``dt`` seconds earlier, or ``None``.
        dt: the time [s] since ``earlier``.

    Returns:
        One :class:`SeenRobot` per cluster.
    """
    pts = np.asarray(dyn_points, dtype=float).reshape(-1, 2)
    labels, n = cluster_points(pts)
    if n == 0:
        return []
    centres = _centres_of(pts, labels, n, viewer_xy, CENTRE_DEPTH)
    if earlier is None:
        vel = np.full((n, 2), np.nan)
    else:
        vel = estimate_velocities(centres, earlier, dt)
    return [SeenRobot(centres[k], pts[labels == k], vel[k]) for k in range(n)]


class RobotTracker:
    """The robots seen in successive scans, with velocities from the centres seen earlier.

    Keeps the centres of the scans of the last ``velocity_history`` [s]; each new scan's clusters
    are matched to the centres of the kept scan whose age is nearest ``velocity_baseline`` (at
    least ``velocity_min_baseline`` old), so a velocity is averaged over about that long.

    Args:
        cfg: ``velocity_history``, ``velocity_min_baseline`` and ``velocity_baseline`` [s].
    """

    def __init__(self, cfg: PerceptionConfig):
        self.cfg = cfg
        self._history: list[tuple[float, np.ndarray]] = []

    def update(self, dyn_points: Points2D, viewer_xy, now: float) -> list[SeenRobot]:
        """The robots of a new scan (:func:`perceive_robots`); remembers their centres.

        Args:
            dyn_points: (M, 2) dynamic scan points x, y [m] in ``map`` (:func:`dynamic_points`).
            viewer_xy: (2,) the lidar's (or robot's) x, y [m].
            now: the scan's time [s].

        Returns:
            One :class:`SeenRobot` per cluster; velocities NaN until a scan at least
            ``velocity_min_baseline`` older is known (or where no earlier centre matched).
        """
        cfg = self.cfg
        self._history = [(t, c) for t, c in self._history
                         if now - t <= cfg.velocity_history and t < now]
        old = [(t, c) for t, c in self._history if now - t >= cfg.velocity_min_baseline]
        earlier, dt = (None, 0.0)
        if old:
            t_old, earlier = min(old, key=lambda tc: abs(now - tc[0] - cfg.velocity_baseline))
            dt = now - t_old
        robots = perceive_robots(dyn_points, viewer_xy, earlier, dt)
        self._history.append((now, robot_centres(robots)))
        return robots


@dataclass(frozen=True)
class SeenArrays:
    """The robots of one scan as arrays, for checks over all of them at once.

    Attributes:
        centres: (K, 2) centres x, y [m] in ``map``.
        velocity: (K, 2) velocities [m/s] (NaN: unknown).
        known: (K,) whether the velocity is known (finite).
        speed: (K,) speeds [m/s], 0 where unknown.
        points: (P, 2) every robot's points x, y [m] in ``map``, robot after robot.
        owner: (P,) the robot index of each point.
        starts: (K,) the index of each robot's first point in ``points``.
        sizes: (K,) the number of each robot's points.
    """

    centres: np.ndarray
    velocity: np.ndarray
    known: np.ndarray
    speed: np.ndarray
    points: np.ndarray
    owner: np.ndarray
    starts: np.ndarray
    sizes: np.ndarray

    @classmethod
    def of(cls, robots: list[SeenRobot]) -> SeenArrays:
        """The arrays of ``robots`` (in their order)."""
        if not robots:
            z2, zi = np.zeros((0, 2)), np.zeros(0, dtype=int)
            return cls(z2, z2, np.zeros(0, dtype=bool), np.zeros(0), z2, zi, zi, zi)
        velocity = np.array([r.velocity for r in robots], dtype=float)
        known = np.isfinite(velocity).all(axis=1)
        speed = np.where(known, np.hypot(velocity[:, 0], velocity[:, 1]), 0.0)
        sizes = np.array([len(r.points) for r in robots], dtype=int)
        starts = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(int)
        return cls(robot_centres(robots), velocity, known, speed,
                   np.vstack([r.points for r in robots]),
                   np.repeat(np.arange(len(robots)), sizes), starts, sizes)


def robot_centres(robots: list[SeenRobot]) -> np.ndarray:
    """(K, 2) the centres x, y [m] of ``robots`` ((0, 2) when there are none)."""
    return np.array([r.centre for r in robots]) if robots else np.zeros((0, 2))
