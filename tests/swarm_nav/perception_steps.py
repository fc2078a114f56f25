"""The perception's steps one at a time, for the tests: clustering, centres, velocities.

The navigator perceives a scan in one compiled call (:func:`swarm_nav.perception.perceive`);
these wrappers call its kernels (:mod:`swarm_nav.perception_kernels`) one by one, with the
arguments the navigator gives them, so that each step can be tested, and held against the numpy
and scipy code it replaced (tests/swarm_nav/test_perception_kernels.py), alone.
"""

from __future__ import annotations

import numpy as np

from swarm_common.geometry import Points2D
from swarm_nav import perception_kernels as kern
from swarm_nav.perception import CENTRE_DEPTH, SeenArrays, SeenRobot, perceive


def cluster_points(points: Points2D, link: float = 0.2) -> tuple[np.ndarray, int]:
    """Group points at most ``link`` [m] apart (single linkage); clusters are numbered in the
    order of their first point.

    Args:
        points: (M, 2) x, y [m].
        link: the linking distance [m].

    Returns:
        ``(labels, n)``: (M,) int cluster index of each point, and the number of clusters.

    Raises:
        ValueError: more than one point and a coordinate is NaN or infinite.
    """
    pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 2))
    labels, n = kern.cluster_labels(pts, float(link))
    if n < 0:
        raise ValueError("data must be finite, check for nan or inf values")
    return labels, n


def cluster_centres(points: Points2D, viewer_xy, link: float = 0.2,
                    depth: float = CENTRE_DEPTH) -> np.ndarray:
    """(K, 2) x, y [m] of the estimated centres of the clusters of (M, 2) points [m] in ``map``:
    each centroid pushed ``depth`` [m] away from the viewer at ``viewer_xy`` (2,) [m]."""
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    labels, n = cluster_points(pts, link)
    return centres_of(pts, labels, n, viewer_xy, depth)


def centres_of(pts: np.ndarray, labels: np.ndarray, n: int, viewer_xy, depth: float
               ) -> np.ndarray:
    """(n, 2) the centres of the clusters ``labels`` of ``pts`` (see :func:`cluster_centres`)."""
    if n == 0:
        return np.zeros((0, 2))
    v = np.asarray(viewer_xy, dtype=float).reshape(2)
    return kern.cluster_centres(np.ascontiguousarray(pts), np.asarray(labels, dtype=np.int64),
                                int(n), float(v[0]), float(v[1]), float(depth))


def estimate_velocities(centres: np.ndarray, earlier: np.ndarray, dt: float,
                        gate: float = 0.3, max_speed: float = 0.5) -> np.ndarray:
    """(K, 2) velocities [m/s] of (K, 2) centres [m] from the nearest of (J, 2) centres ``dt``
    [s] earlier, at most ``gate + max_speed * dt`` [m] away; NaN where none matched."""
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    e = np.asarray(earlier, dtype=float).reshape(-1, 2)
    if len(c) == 0 or len(e) == 0 or dt <= 0:
        return np.full(c.shape, np.nan)
    return kern.match_velocities(np.ascontiguousarray(c), np.ascontiguousarray(e), float(dt),
                                 gate + max_speed * dt)


def perceive_robots(dyn_points: Points2D, viewer_xy, earlier: np.ndarray | None = None,
                    dt: float = 0.0) -> list[SeenRobot]:
    """The robots of :func:`swarm_nav.perception.perceive`, without their arrays."""
    return perceive(dyn_points, viewer_xy, earlier, dt)[0]


def robot_centres(robots: list[SeenRobot]) -> np.ndarray:
    """(K, 2) the centres x, y [m] of ``robots`` ((0, 2) when there are none)."""
    return np.array([r.centre for r in robots]) if robots else np.zeros((0, 2))


def seen_arrays_of(robots: list[SeenRobot]) -> SeenArrays:
    """The :class:`SeenArrays` of ``robots`` (in their order), gathered from the robots."""
    if not robots:
        return SeenArrays.empty()
    velocity = np.array([r.velocity for r in robots], dtype=float)
    known, speed = kern.speeds(velocity)
    sizes = np.array([len(r.points) for r in robots], dtype=int)
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1])).astype(int)
    return SeenArrays(robot_centres(robots), velocity, known, speed,
                      np.vstack([r.points for r in robots]),
                      np.repeat(np.arange(len(robots)), sizes), starts, sizes)
