"""What a robot sees of the other robots in its own scan: clusters, centres and velocities.

No communication: every robot knows the others only through its lidar. The scan points that the
static map does not explain (farther than ``static_point_tolerance`` from every lethal cell,
:func:`dynamic_points`) are grouped by single linkage; each cluster is one robot
(:class:`SeenRobot`) whose centre lies a little behind its visible side and whose velocity comes
from matching the centres to those of a scan about ``velocity_baseline`` earlier
(:func:`perceive`; :class:`RobotTracker` keeps that short history). :class:`ObstacleSet` keeps
what one navigator sees (the scan, the robots in it, the walls near the robot, where the robots
seen moving will be) for the holding pattern, the traffic rules and the navigator
(:mod:`swarm_nav.core`).

The loops run compiled (:mod:`swarm_nav.perception_kernels`, numba), with the same results to the
last bit as the numpy and scipy code they replaced (tests/swarm_nav/test_perception_kernels.py).

Pure: numpy arrays in ``map`` and dataclasses, no ROS. Tests: tests/swarm_nav/test_perception.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarm_common.geometry import Points2D
from swarm_nav import perception_kernels as kern
from swarm_nav.config import NavigatorConfig, PerceptionConfig
from swarm_nav.costmap import Costmap
from swarm_nav.dwa import Footprint, point_gaps

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
    if type(costmap) is Costmap:  # Costmap.distance_at's lookup, compiled
        keep, ok = kern.dynamic_mask(np.ascontiguousarray(pts), float(costmap.origin[0]),
                                     float(costmap.origin[1]), float(costmap.resolution),
                                     costmap.obstacle_distance, float(tolerance))
        if ok:
            return pts[keep]
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


_LINK = 0.2  # [m] scan points at most this far apart belong to one robot (single linkage)
_GATE = 0.3  # [m] a centre matches one of a scan dt earlier at most _GATE + _MAX_SPEED dt away
_MAX_SPEED = 0.5  # [m/s] the fastest a robot seen is taken to move
_NO_CENTRES = np.zeros((0, 2))


def perceive(dyn_points: Points2D, viewer_xy, earlier: np.ndarray | None = None, dt: float = 0.0
             ) -> tuple[list[SeenRobot], SeenArrays | None]:
    """The other robots in a scan: clusters of dynamic points, their centres and velocities.

    Points at most ``_LINK`` apart are one cluster (single linkage: ``dx * dx + dy * dy <= link
    * link``, the test of scipy's ``cKDTree.query_pairs``); clusters are numbered in the order of
    their first point. Each cluster is a robot whose centre is its centroid pushed
    ``CENTRE_DEPTH`` away from the viewer (a lidar sees an object's near side), and whose
    velocity matches its centre to the nearest of ``earlier`` (at most ``_GATE + _MAX_SPEED *
    dt`` away; NaN otherwise). One compiled call (:func:`swarm_nav.perception_kernels.perceive`).

    Args:
        dyn_points: (M, 2) dynamic scan points x, y [m] in ``map`` (:func:`dynamic_points`).
        viewer_xy: (2,) the lidar's (or robot's) x, y [m].
        earlier: (J, 2) the centres [m] seen ``dt`` seconds earlier, or ``None``.
        dt: the time [s] since ``earlier``.

    Returns:
        ``(robots, seen)``: one :class:`SeenRobot` per cluster, and the same as
        :class:`SeenArrays` (``None`` when no robot is seen).

    Raises:
        ValueError: more than one point and a coordinate is NaN or infinite.
    """
    pts = np.ascontiguousarray(np.asarray(dyn_points, dtype=float).reshape(-1, 2))
    v = np.asarray(viewer_xy, dtype=float).reshape(2)
    if earlier is None:
        e, dt, reach = _NO_CENTRES, 0.0, 0.0
    else:
        e = np.ascontiguousarray(np.asarray(earlier, dtype=float).reshape(-1, 2))
        reach = _GATE + _MAX_SPEED * dt
    n, centres, vel, grouped, starts, sizes, owner, known, speed = kern.perceive(
        pts, _LINK, float(v[0]), float(v[1]), CENTRE_DEPTH, e, float(dt), reach)
    if n < 0:
        raise ValueError("data must be finite, check for nan or inf values")
    if n == 0:
        return [], None
    ends = (starts + sizes).tolist()
    robots = [SeenRobot(c, grouped[a:b], u)
              for c, a, b, u in zip(centres, starts.tolist(), ends, vel, strict=True)]
    # the arrays apart from the robots', so neither sees the other's changes
    return robots, SeenArrays(centres.copy(), vel.copy(), known, speed, grouped.copy(), owner,
                              starts, sizes)


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

    def update(self, dyn_points: Points2D, viewer_xy, now: float
               ) -> tuple[list[SeenRobot], SeenArrays]:
        """The robots of a new scan (:func:`perceive`); remembers their centres.

        Args:
            dyn_points, viewer_xy: as :func:`perceive`'s; now: the scan's time [s].

        Returns:
            ``(robots, seen)``: one :class:`SeenRobot` per cluster, velocities NaN until a scan
            at least ``velocity_min_baseline`` older is known (or where no earlier centre
            matched), and the same robots as :class:`SeenArrays`.
        """
        cfg = self.cfg
        self._history = [(t, c) for t, c in self._history
                         if now - t <= cfg.velocity_history and t < now]
        earlier, dt = (None, 0.0)
        best = None
        for t, c in self._history:  # the first of the kept scans nearest the baseline
            if now - t >= cfg.velocity_min_baseline:
                off = abs(now - t - cfg.velocity_baseline)
                if best is None or off < best:
                    best, earlier, dt = off, c, now - t
        robots, seen = perceive(dyn_points, viewer_xy, earlier, dt)
        if seen is None:
            seen = SeenArrays.empty()
        self._history.append((now, seen.centres.copy()))
        return robots, seen


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
    def empty(cls) -> SeenArrays:
        """No robot: arrays of length 0."""
        z2, zi = np.zeros((0, 2)), np.zeros(0, dtype=int)
        return cls(z2, z2, np.zeros(0, dtype=bool), np.zeros(0), z2, zi, zi, zi)


_STATIC_MARGIN = 0.5  # [m] the robot moves this far before its static obstacle window is renewed
_EPS = 1e-6  # [m] ... which is grown by this too (no rounding at its edge can drop a point)


class ObstacleSet:
    """What one navigator sees: the last scan, the robots in it, the static walls near the robot.

    Args:
        cfg: ``perception``, ``scan_max_age`` [s], ``obstacle_window`` [m], ``prediction_step``
            and ``prediction_max`` [s], ``holding.moving_speed`` [m/s], ``dwa.footprint_padding``.
        footprint: the robot's footprint box.

    Attributes:
        costmap: the static costmap (set with the map), or ``None``.
        scan: (M, 2) the last scan's end points x, y [m] in ``map``.
        dynamic: (K, 2) those the static map does not explain (:func:`dynamic_points`).
        robots: the robots seen in it; ``seen``: the same as :class:`SeenArrays`.
        time: the scan's time [s] (``-inf`` before the first).
    """

    def __init__(self, cfg: NavigatorConfig, footprint: Footprint):
        self.cfg = cfg
        self.footprint = footprint
        self.costmap: Costmap | None = None
        self.scan = np.zeros((0, 2))
        self.dynamic = np.zeros((0, 2))
        self.robots: list[SeenRobot] = []
        self.seen = SeenArrays.empty()
        self.time = -math.inf
        self._movers = self._moving_points()
        self._tracker = RobotTracker(cfg.perception)
        self._superset = np.zeros((0, 2))  # boundary points near _centre
        self._centre: np.ndarray | None = None
        self._source: np.ndarray | None = None  # the boundary array it was taken from

    def update(self, points_map: Points2D, viewer_xy, now: float) -> None:
        """Take a scan's end points (M, 2) x, y [m] in ``map`` (non-finite rows are dropped),
        seen from ``viewer_xy`` (2,) [m] at ``now`` [s]."""
        pts = np.asarray(points_map, dtype=float).reshape(-1, 2)
        pts = kern.finite_rows(np.ascontiguousarray(pts))
        self.scan = pts
        self.time = now
        if self.costmap is None:
            self.dynamic = pts
        else:
            self.dynamic = dynamic_points(pts, self.costmap,
                                          self.cfg.perception.static_point_tolerance)
        self.robots, self.seen = self._tracker.update(self.dynamic, viewer_xy, now)
        self._movers = self._moving_points()

    def fresh(self, now: float) -> bool:
        """Whether the scan is at most ``scan_max_age`` old at ``now`` [s] (only a fresh scan's
        robots judge the goal and the path ahead)."""
        return now - self.time <= self.cfg.scan_max_age

    def moving(self) -> np.ndarray:
        """(K,) whether each robot seen moves faster than ``holding.moving_speed``."""
        return self.seen.known & (self.seen.speed > self.cfg.holding.moving_speed)

    def obstacles(self, pose: np.ndarray, now: float) -> np.ndarray:
        """(P, 2) x, y [m] in ``map``: the scan, the walls near ``pose`` (:meth:`static_near`)
        and where the robots seen moving will be at ``now`` [s] (:meth:`predicted`)."""
        parts = [self.scan, self.static_near(pose), self.predicted(pose, now)]
        parts = [p for p in parts if len(p)]
        return np.vstack(parts) if parts else np.zeros((0, 2))

    def predicted(self, pose: np.ndarray, now: float) -> np.ndarray:
        """(P, 2) x, y [m] in ``map`` where the points of the robots seen moving will be
        ``prediction_step`` and twice that after the scan, plus its age at ``now`` [s] (at most
        ``prediction_max``); none already within ``footprint_padding`` of the robot at ``pose``.

        The DWA relaxes its padding to the current gap when the robot already is that near (so
        that it can leave a tight spot), and a point that is only a guess must not relax it
        against the points that are really there (why: docs/design/navigator.md#prediction).
        """
        cfg = self.cfg
        lag = max(0.0, now - self.time)
        step = cfg.prediction_step
        taus = [min(tau, cfg.prediction_max) for tau in (lag + step, lag + 2.0 * step)]
        points, velocity, later = self._movers
        if not len(points):
            return np.zeros((0, 2))
        ahead = points + velocity * np.where(later, taus[1], taus[0])[:, None]
        # all robots' predictions in one point_gaps call (it is per point)
        return ahead[point_gaps(pose, ahead, self.footprint) >= cfg.dwa.footprint_padding]

    def _moving_points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points of the robots seen moving, each robot's twice (its points for the earlier
        prediction time, then for the later one): (P, 2) points x, y [m] in ``map``, (P, 2) their
        robot's velocity [m/s], (P,) whether the point is for the later time."""
        seen = self.seen
        return kern.moving_points(seen.points, seen.starts, seen.sizes, seen.velocity,
                                  self.moving())

    def static_near(self, pose: np.ndarray) -> np.ndarray:
        """(K, 2) the static map's boundary points within ``obstacle_window`` (per axis) of pose.

        Filtered from a cached superset (the window grown by ``_STATIC_MARGIN``, taken about where
        the robot stood) that is renewed once the robot has moved ``_STATIC_MARGIN``: the same
        points in the same order as filtering the whole boundary, without reading all of it
        every tick.
        """
        if self.costmap is None:
            return np.zeros((0, 2))
        stat = self.costmap.boundary_points()
        r = self.cfg.obstacle_window
        c = self._centre
        if (self._source is not stat or c is None
                or abs(pose[0] - c[0]) > _STATIC_MARGIN or abs(pose[1] - c[1]) > _STATIC_MARGIN):
            grown = r + _STATIC_MARGIN + _EPS
            m = (np.abs(stat[:, 0] - pose[0]) < grown) & (np.abs(stat[:, 1] - pose[1]) < grown)
            self._superset = stat[m]
            self._centre = pose[:2].copy()
            self._source = stat
        near = self._superset
        m = (np.abs(near[:, 0] - pose[0]) < r) & (np.abs(near[:, 1] - pose[1]) < r)
        return near[m]
