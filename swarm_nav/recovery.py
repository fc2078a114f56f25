"""Progress checking, recovery behaviours, and the rules that break deadlocks between robots.

- :class:`ProgressChecker` is nav2's SimpleProgressChecker: the robot must move
  ``required_movement_radius`` (0.5 m) from where it was within ``movement_time_allowance`` (10 s).
- :class:`Recovery` runs one behaviour of nav2's recovery set (replan with the robots seen, back
  up, wait, spin) and checks each motion against the scan before commanding it.
- :func:`keep_right` is the traffic rule that lets two robots meeting head-on pass without any
  communication: each shifts its local path to its own right when a robot is ahead on it.
- :func:`must_yield` breaks what is left of a face-to-face deadlock with a rule both robots
  evaluate to opposite answers from what each sees: the robot whose bearing to the other points
  along the yield axis yields (it retreats to a place off the other's way, found by
  :func:`retreat_candidates`, and waits until its path is clear); the other keeps going.
- The robot's namespace index only staggers the wait time, so that several robots that are stuck
  together do not retry in lockstep.
"""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np

from swarm_common.geometry import Path2D, Points2D, wrap_angle
from swarm_nav.config import RecoveryConfig
from swarm_nav.costmap import INSCRIBED, Costmap
from swarm_nav.dwa import Footprint, footprint_gaps, rotation_is_safe


class ProgressChecker:
    """nav2's SimpleProgressChecker.

    Args:
        cfg: ``required_movement_radius`` [m] and ``movement_time_allowance`` [s].
    """

    def __init__(self, cfg: RecoveryConfig):
        self.cfg = cfg
        self._anchor: np.ndarray | None = None
        self._since = 0.0

    def reset(self, pose, now: float) -> None:
        """Start measuring from ``pose`` (3,) or (2,) [m] at time ``now`` [s]."""
        self._anchor = np.asarray(pose, dtype=float)[:2].copy()
        self._since = now

    def check(self, pose, now: float) -> bool:
        """Whether the robot is making progress.

        Args:
            pose: (3,) or (2,) the robot's position [m] in ``map``.
            now: time [s].

        Returns:
            False when the robot has stayed within ``required_movement_radius`` of the anchor for
            ``movement_time_allowance``; moving that far re-anchors.
        """
        xy = np.asarray(pose, dtype=float)[:2]
        if self._anchor is None or np.hypot(*(xy - self._anchor)) >= (
                self.cfg.required_movement_radius):
            self.reset(xy, now)
            return True
        return now - self._since < self.cfg.movement_time_allowance


class RecoveryKind(StrEnum):
    """The recovery behaviours, in the order they are tried."""

    REPLAN = "replan"   # nav2's "clear costmaps": plan again, around the robots seen
    BACKUP = "backup"
    WAIT = "wait"
    SPIN = "spin"


SEQUENCE = (RecoveryKind.REPLAN, RecoveryKind.BACKUP, RecoveryKind.WAIT, RecoveryKind.SPIN)


def wait_time(cfg: RecoveryConfig, robot_index: int) -> float:
    """The wait [s] of robot ``robot_index``: ``wait_duration * (1 + (index % 3) / 2)``."""
    return cfg.wait_duration * (1.0 + (robot_index % 3) / 2.0)


class Recovery:
    """One running recovery behaviour.

    Args:
        kind: the behaviour.
        pose: (3,) the robot's pose [m, rad] in ``map`` when it starts.
        now: the start time [s].
        cfg: the recovery settings.
        footprint: the robot's footprint box.
        padding: safety margin [m] around the footprint (the DWA's ``footprint_padding``).
        robot_index: the robot's namespace index (staggers the wait).
        spin_sign: +1 to spin counter-clockwise, -1 clockwise.
        wait: the wait [s]; ``None`` for :func:`wait_time`.
    """

    def __init__(self, kind: RecoveryKind, pose, now: float, cfg: RecoveryConfig,
                 footprint: Footprint, padding: float, robot_index: int = 0,
                 spin_sign: float = 1.0, wait: float | None = None):
        self.kind = kind
        self.start = np.asarray(pose, dtype=float).copy()
        self.t0 = now
        self.cfg = cfg
        self.footprint = footprint
        self.padding = padding
        self.spin_sign = 1.0 if spin_sign >= 0 else -1.0
        self.wait = wait_time(cfg, robot_index) if wait is None else wait
        self._turned = 0.0
        self._last_yaw = float(self.start[2])

    def step(self, pose, obstacles: Points2D, now: float) -> tuple[float, float, bool]:
        """The command of this tick.

        Args:
            pose: (3,) the robot's pose [m, rad] in ``map``.
            obstacles: (M, 2) obstacle points x, y [m] in ``map``.
            now: time [s].

        Returns:
            ``(v [m/s], w [rad/s], done)``; ``done`` when the behaviour finished, timed out or
            could not go on safely (the command is then a stop).
        """
        pose = np.asarray(pose, dtype=float)
        elapsed = now - self.t0
        if self.kind == RecoveryKind.REPLAN:
            return 0.0, 0.0, True
        if self.kind == RecoveryKind.WAIT:
            return 0.0, 0.0, elapsed >= self.wait
        if elapsed >= self.cfg.time_allowance:
            return 0.0, 0.0, True
        if self.kind == RecoveryKind.BACKUP:
            if np.hypot(*(pose[:2] - self.start[:2])) >= self.cfg.backup_dist:
                return 0.0, 0.0, True
            if not backup_is_safe(pose, self.cfg.backup_speed, obstacles, self.footprint,
                                  self.padding, horizon=0.3):
                return 0.0, 0.0, True
            return -self.cfg.backup_speed, 0.0, False
        # SPIN
        self._turned += abs(wrap_angle(pose[2] - self._last_yaw))
        self._last_yaw = float(pose[2])
        left = self.cfg.spin_dist - self._turned
        if left <= 0.05:
            return 0.0, 0.0, True
        if not rotation_is_safe(pose, self.spin_sign * min(0.3, left), obstacles, self.footprint,
                                self.padding):
            return 0.0, 0.0, True
        return 0.0, self.spin_sign * min(1.0, max(0.3, left)), False


def backup_is_safe(pose, speed: float, obstacles: Points2D, footprint: Footprint,
                   padding: float, horizon: float = 1.0) -> bool:
    """Whether backing up straight at ``speed`` [m/s] for ``horizon`` [s] stays clear.

    Args:
        pose: (3,) the robot's pose [m, rad] in ``map``.
        speed: backing speed [m/s] (positive).
        obstacles: (M, 2) obstacle points x, y [m] in ``map``.
        footprint: the footprint box.
        padding: the safety margin [m]; a robot already nearer may back up if it gets no nearer.
        horizon: how long [s] the motion is checked.

    Returns:
        True if no point enters the padded footprint along the way.
    """
    pose = np.asarray(pose, dtype=float)
    d = np.linspace(0.0, -speed * horizon, 6)
    x = pose[0] + d * math.cos(pose[2])
    y = pose[1] + d * math.sin(pose[2])
    pts = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return True
    near = np.hypot(pts[:, 0] - pose[0], pts[:, 1] - pose[1]) < footprint.radius + 0.5
    gaps = footprint_gaps(x, y, np.full(6, pose[2]), pts[near], footprint)
    dip = 0.5 * speed * horizon / 5  # what the steps may skip over
    return bool(gaps[1:].min() - dip >= min(padding, gaps[0]))


def robots_ahead(pose, centres: np.ndarray, distance: float, half_angle: float = math.pi / 3
                 ) -> np.ndarray:
    """Indices of the robot centres within ``distance`` [m] in front of the robot.

    Args:
        pose: (3,) the robot's pose [m, rad] in ``map``.
        centres: (K, 2) other robots' estimated centres x, y [m] in ``map``.
        distance: how far ahead [m].
        half_angle: half the opening [rad] of the cone in front.

    Returns:
        (J,) indices into ``centres``, nearest first.
    """
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    if len(c) == 0:
        return np.zeros(0, dtype=int)
    d = c - np.asarray(pose, dtype=float)[:2]
    rng = np.hypot(d[:, 0], d[:, 1])
    bearing = np.abs(wrap_angle(np.arctan2(d[:, 1], d[:, 0]) - pose[2]))
    idx = np.flatnonzero((rng <= distance) & (bearing <= half_angle))
    return idx[np.argsort(rng[idx])]


def must_yield(robot_xy, other_xy, axis_angle: float) -> bool:
    """The deadlock rule: the robot whose bearing to the other points along the axis yields.

    Both robots evaluate it from their own position and their estimate of the other's; the
    bearings are opposite, so exactly one yields (the axis is tilted off the map axes so that the
    corridors of a factory floor, which run along x or y, are never ambiguous).

    Args:
        robot_xy: (2,) our position [m] in ``map``.
        other_xy: (2,) the other robot's estimated centre [m].
        axis_angle: direction [rad] of the yield axis in ``map``.

    Returns:
        True if we yield.
    """
    d = np.asarray(other_xy, dtype=float) - np.asarray(robot_xy, dtype=float)
    return bool(d[0] * math.cos(axis_angle) + d[1] * math.sin(axis_angle) > 0.0)


def keep_right(path: Path2D, pose, centres: np.ndarray, costmap: Costmap,
               cfg: RecoveryConfig, lateral: float = 0.7, max_cost: int = 200) -> Path2D:
    """Shift the local path to the robot's right while another robot is ahead on it.

    Every robot applies the same rule to its own path, so two robots meeting head-on move apart
    before they meet, like traffic.  The shift grows in over the first 0.5 m of the local path and
    shrinks where the costmap has no room for it: a shifted point may cost at most ``max_cost``
    (or what the unshifted point costs, if more); the largest of 1, 2/3, 1/3 and 0 times the
    offset that satisfies this is used.

    Args:
        path: (N, 2) local path x, y [m] in ``map`` from near the robot onward.
        pose: (3,) the robot's pose [m, rad].
        centres: (K, 2) other robots' estimated centres [m].
        costmap: the static costmap.
        cfg: ``keep_right_offset`` [m] and ``keep_right_distance`` [m].
        lateral: a robot counts as "on the path" within this distance [m] of it.
        max_cost: the costmap cost a shifted point may reach (200: about 0.3 m from walls with
            nav2's default inflation).

    Returns:
        (N, 2) the shifted path (the input when no robot is ahead on it).
    """
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    c = np.asarray(centres, dtype=float).reshape(-1, 2)
    if len(path) < 2 or len(c) == 0 or cfg.keep_right_offset <= 0.0:
        return path
    ahead = robots_ahead(pose, c, cfg.keep_right_distance, math.pi / 2)
    if len(ahead) == 0:
        return path
    d = np.hypot(c[ahead, None, 0] - path[None, :, 0], c[ahead, None, 1] - path[None, :, 1])
    if d.min() > lateral:
        return path
    seg = np.diff(path, axis=0)
    tang = np.vstack((seg, seg[-1:]))
    tang /= np.maximum(np.hypot(tang[:, 0], tang[:, 1]), 1e-9)[:, None]
    right = np.column_stack((tang[:, 1], -tang[:, 0]))
    s = np.concatenate(([0.0], np.cumsum(np.hypot(seg[:, 0], seg[:, 1]))))
    ramp = np.clip(s / 0.5, 0.0, 1.0)
    best = np.zeros(len(path))
    limit = np.maximum(costmap.cost_at(path).astype(int), max_cost)
    for frac in (1.0 / 3.0, 2.0 / 3.0, 1.0):
        cand = path + (frac * cfg.keep_right_offset * ramp)[:, None] * right
        c = costmap.cost_at(cand).astype(int)
        best = np.where((c <= limit) & (c < INSCRIBED), frac, best)
    return path + (best * cfg.keep_right_offset * ramp)[:, None] * right


def retreat_candidates(costmap: Costmap, robot_xy, other_xy, cfg: RecoveryConfig,
                       max_cost: int = 128) -> np.ndarray:
    """Places a robot that yields may retreat to, nearest first.

    The other robot is taken to come along the line from itself through us.  A candidate is the
    centre of a cell within ``yield_search_radius`` of us, cheaper than ``max_cost`` (well clear of
    walls), in our connected component, at least ``yield_clearance`` off that line, and not beyond
    the other robot.

    Args:
        costmap: the costmap (static, or with the robots seen overlaid).
        robot_xy: (2,) our position x, y [m] in ``map``.
        other_xy: (2,) the other robot's estimated centre [m].
        cfg: ``yield_search_radius`` [m] and ``yield_clearance`` [m].
        max_cost: the highest cost a candidate cell may have.

    Returns:
        (K, 2) candidate x, y [m], sorted by straight-line distance from us.
    """
    robot_xy = np.asarray(robot_xy, dtype=float)[:2]
    other_xy = np.asarray(other_xy, dtype=float)[:2]
    axis = robot_xy - other_xy
    norm = float(np.hypot(*axis))
    axis = axis / norm if norm > 1e-6 else np.array([1.0, 0.0])
    res = costmap.resolution
    n = int(math.ceil(cfg.yield_search_radius / res))
    rc = costmap.world_to_cell(robot_xy)
    r0, r1 = max(rc[0] - n, 0), min(rc[0] + n + 1, costmap.height)
    c0, c1 = max(rc[1] - n, 0), min(rc[1] + n + 1, costmap.width)
    if r0 >= r1 or c0 >= c1 or not costmap.in_bounds(rc):
        return np.zeros((0, 2))
    labels = costmap.components(False)
    mine = labels[rc[0], rc[1]]
    win = (costmap.costs[r0:r1, c0:c1] < max_cost)
    if mine:
        win &= labels[r0:r1, c0:c1] == mine
    cells = np.argwhere(win) + (r0, c0)
    if len(cells) == 0:
        return np.zeros((0, 2))
    xy = costmap.cell_to_world(cells)
    rel = xy - other_xy
    along = rel @ axis
    lateral = np.abs(rel[:, 0] * axis[1] - rel[:, 1] * axis[0])
    dist = np.hypot(*(xy - robot_xy).T)
    ok = (lateral >= cfg.yield_clearance) & (along >= -0.3) & (dist <= cfg.yield_search_radius)
    xy, dist = xy[ok], dist[ok]
    return xy[np.argsort(dist, kind="stable")]
