"""Progress checking and recovery behaviours (nav2's progress checker and recovery set).

- :class:`ProgressChecker` is nav2's SimpleProgressChecker: the robot must move
  ``required_movement_radius`` (0.5 m) from where it was within ``movement_time_allowance`` (10 s).
- :class:`Recovery` runs one behaviour of nav2's recovery set (replan with the robots seen, back
  up, wait, spin) and checks each motion against the scan before commanding it.
- The rules between robots (keep right, and who yields in a face-to-face deadlock) live in
  :mod:`swarm_nav.traffic`.
- A robot packed in among others or against a wall (a knot: a robot or a wall within
  ``escape_clearance`` of its footprint) that a whole cycle has not freed escapes instead of
  waiting (:func:`escape_command`).
- The robot's namespace index only staggers the wait time, so that several robots that are stuck
  together do not retry in lockstep.
"""

from __future__ import annotations

import math
from enum import StrEnum

import numpy as np

from swarm_common.geometry import Points2D, wrap_angle
from swarm_nav.config import RecoveryConfig
from swarm_nav.dwa import Footprint, footprint_gaps, point_gaps, rotation_is_safe


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
    ESCAPE = "escape"  # not nav2's: widen the smallest gap to the robots (or wall) packed about us


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
        if self.kind == RecoveryKind.ESCAPE:
            cmd = escape_command(pose, obstacles, self.footprint, self.cfg)
            if cmd is None:
                return 0.0, 0.0, True
            return cmd[0], cmd[1], False
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


def escape_command(pose, obstacles: Points2D, footprint: Footprint, cfg: RecoveryConfig,
                   horizon: float = 0.5) -> tuple[float, float] | None:
    """The motion that takes a robot packed in a knot farthest out of it.

    Robots that stand body to body (gaps of 5-6 cm, the DWA's padding) find no admissible arc
    along their paths, since every arc of the DWA's horizon closes some gap, and nav2's recoveries
    do not free them either (why: docs/design/navigator.md#knots). A robot of the knot descends
    the repulsion potential ``U = sum_p exp(-gap_p / s)`` of the obstacle points ``p`` near it
    (``s`` = ``escape_clearance / 3``; ``gap_p`` the footprint's gap to ``p``), never coming
    nearer than ``escape_padding`` to any point (nor nearer than it is, if it is already): it
    slides out of a robot's flank, which the smallest gap alone does not see (two robots side
    by side keep that gap until they no longer overlap).

    The candidates are the 5 x 5 pairs of ``v`` in ``[-1, 1] * escape_speed`` and ``w`` in
    ``[-1, 1] * escape_turn``, rolled out as arcs for ``horizon``; an admissible one (its
    smallest gap, less what the steps may skip, stays at least ``min(escape_padding, gap now)``)
    of least ``U`` at its end wins if it lowers ``U`` by 1 % or more. ``escape_padding`` is below
    the DWA's padding: at that padding two robots side by side cannot even turn away.

    Args:
        pose: (3,) the robot's pose [m, rad] in ``map``.
        obstacles: (M, 2) obstacle points x, y [m] in ``map`` (scan and walls).
        footprint: the footprint box.
        cfg: ``escape_clearance`` [m], ``escape_padding`` [m], ``escape_speed`` [m/s] and
            ``escape_turn`` [rad/s].
        horizon: how long [s] each candidate is rolled out.

    Returns:
        ``(v [m/s], w [rad/s])``, or ``None`` when the smallest gap already is
        ``escape_clearance`` or no candidate lowers ``U``.
    """
    pose = np.asarray(pose, dtype=float)
    pts = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    if len(pts) == 0 or cfg.escape_clearance <= 0:
        return None
    pts = pts[np.hypot(pts[:, 0] - pose[0], pts[:, 1] - pose[1])
              < footprint.radius + cfg.escape_clearance + cfg.escape_speed * horizon]
    if len(pts) == 0:
        return None
    now_gaps = point_gaps(pose, pts, footprint)
    gap_now = float(now_gaps.min())
    if gap_now >= cfg.escape_clearance:
        return None
    scale = cfg.escape_clearance / 3.0
    u_now = float(np.exp(-np.maximum(now_gaps, 0.0) / scale).sum())
    vs, ws = np.meshgrid(np.linspace(-1.0, 1.0, 5) * cfg.escape_speed,
                         np.linspace(-1.0, 1.0, 5) * cfg.escape_turn, indexing="ij")
    vs, ws = vs.ravel(), ws.ravel()
    t = np.linspace(0.0, horizon, 7)[1:]
    th = pose[2] + ws[:, None] * t
    straight = np.abs(ws) < 1e-9
    w_safe = np.where(straight, 1.0, ws)
    # exact arcs: x = x0 + v/w (sin(th) - sin(th0)), y = y0 - v/w (cos(th) - cos(th0))
    dx = np.where(straight[:, None], (vs[:, None] * t) * math.cos(pose[2]),
                  vs[:, None] / w_safe[:, None] * (np.sin(th) - math.sin(pose[2])))
    dy = np.where(straight[:, None], (vs[:, None] * t) * math.sin(pose[2]),
                  -vs[:, None] / w_safe[:, None] * (np.cos(th) - math.cos(pose[2])))
    gaps = footprint_gaps(pose[0] + dx, pose[1] + dy, th, pts, footprint)
    step = (cfg.escape_speed + cfg.escape_turn * footprint.radius) * (t[1] - t[0])
    ok = gaps.min(axis=1) - step / 2 >= min(cfg.escape_padding, gap_now)
    ok &= (np.abs(vs) > 0) | (np.abs(ws) > 0)
    if not ok.any():
        return None
    end = np.full(len(vs), np.inf)
    for k in np.flatnonzero(ok):
        g = point_gaps((pose[0] + dx[k, -1], pose[1] + dy[k, -1], th[k, -1]), pts, footprint)
        end[k] = float(np.exp(-np.maximum(g, 0.0) / scale).sum())
    best = int(np.argmin(end))
    if end[best] > 0.99 * u_now:
        return None
    return float(vs[best]), float(ws[best])


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
