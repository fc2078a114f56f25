"""The traffic rules between robots that do not talk to each other: keep right, and who yields.

Every robot applies the same rules to what its own scan shows, so two robots agree without any
communication:

- **Keep right** (:func:`keep_right`): a robot shifts its local path to its own right while a
  robot comes toward it on it (:func:`oncoming_centres`), so two robots meeting head-on in a
  lane move apart before they meet, like road traffic. Without it, two DWAs facing each other
  each steer around the other to the same side about half of the time and end nose to nose.
- **Yield** (:func:`must_yield`): what is left of a face-to-face deadlock (a robot within
  ``deadlock_distance`` ahead, :func:`robots_ahead`, while stuck) is broken by a rule whose answer
  is opposite for the two robots: the one whose bearing to the other points along the yield axis
  (``yield_axis_angle``, tilted off the map axes so that corridors along x or y are never
  ambiguous) yields. It drives to a place off the other's way (:func:`retreat_candidates`,
  :func:`plan_retreat`) and waits there until its path is clear (:class:`Yield`); the other keeps
  going.

Settings: :class:`swarm_nav.config.TrafficConfig`. Pure (numpy, no ROS); the navigator
(:mod:`swarm_nav.core`) calls these. Why: docs/design/navigator.md#keep-right and #yield. Tests:
tests/swarm_nav/test_traffic.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import StrEnum

import numpy as np

from swarm_common.geometry import Path2D, wrap_angle
from swarm_nav.config import PlannerConfig, TrafficConfig
from swarm_nav.costmap import INSCRIBED, Costmap
from swarm_nav.planner import path_length, plan_path

_EPS = 1e-6  # [m] below this a distance counts as zero (no direction)
_NO_RETREAT = 0.05  # [m] a yielding robot that got less far than this from where it began,
#                    when the drive to its retreat place ends stuck, did not retreat at all


def oncoming_centres(centres: np.ndarray, velocities: np.ndarray, robot_xy,
                     moving_speed: float) -> np.ndarray:
    """The robots seen driving toward us: those the keep-right rule makes room for.

    Args:
        centres: (K, 2) the robots' centres x, y [m] in ``map``.
        velocities: (K, 2) their velocities [m/s] (NaN: unknown; such a robot never counts).
        robot_xy: (2,) our position x, y [m] in ``map``.
        moving_speed: a robot counts when its speed toward us exceeds this [m/s].

    Returns:
        (J, 2) the centres x, y [m] of those driving toward us, in the order of ``centres``.
    """
    xy = np.asarray(robot_xy, dtype=float)[:2]
    d = xy - centres
    n = np.hypot(d[:, 0], d[:, 1])
    known = np.isfinite(velocities).all(axis=1)
    with np.errstate(invalid="ignore", divide="ignore"):
        toward = (velocities[:, 0] * d[:, 0] + velocities[:, 1] * d[:, 1]) / n
    out = centres[(n > _EPS) & known & (toward > moving_speed)]
    return out if len(out) else np.zeros((0, 2))


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


KEEP_RIGHT_LATERAL = 0.7  # [m] keep_right's default: a robot this near the path is on it


def keep_right(path: Path2D, pose, centres: np.ndarray, costmap: Costmap,
               cfg: TrafficConfig, lateral: float = KEEP_RIGHT_LATERAL, max_cost: int = 200
               ) -> Path2D:
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
    fracs = (1.0 / 3.0, 2.0 / 3.0, 1.0)
    shifted = [path + (frac * cfg.keep_right_offset * ramp)[:, None] * right for frac in fracs]
    costs = costmap.cost_at(np.stack([path, *shifted])).astype(int)  # one lookup for all
    best = np.zeros(len(path))
    limit = np.maximum(costs[0], max_cost)
    for frac, c in zip(fracs, costs[1:], strict=True):
        best = np.where((c <= limit) & (c < INSCRIBED), frac, best)
    return path + (best * cfg.keep_right_offset * ramp)[:, None] * right


def retreat_candidates(costmap: Costmap, robot_xy, other_xy, cfg: TrafficConfig,
                       max_cost: int = 128) -> np.ndarray:
    """Places a robot that yields may retreat to, nearest first.

    The other robot is taken to come along the line from itself through us.  A candidate is the
    centre of a cell within ``yield_search_radius`` of us, cheaper than ``max_cost`` (well clear of
    walls), in our connected component, at least ``yield_clearance`` off that line, and not beyond
    the other robot.

    Args:
        costmap: the costmap (static, or with the robots seen overlaid).
        robot_xy, other_xy: (2,) our position and the other robot's estimated centre, x, y [m]
            in ``map``.
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


def plan_retreat(costmap: Costmap, robot_xy, other_xy, cfg: TrafficConfig,
                 planner: PlannerConfig) -> Path2D | None:
    """The path to the place a yielding robot retreats to, or ``None`` if there is none.

    The candidates of :func:`retreat_candidates` are tried nearest first, skipping any within
    ``yield_retreat_spacing`` of one already tried, at most ``yield_retreat_tries`` of them; the
    first one with a path no longer than ``yield_detour_factor`` times the straight distance plus
    ``yield_detour_slack`` wins.

    Args:
        costmap: the costmap to plan on (the static one, or with the robots seen overlaid).
        robot_xy, other_xy: (2,) our position and the other robot's estimated centre, x, y [m]
            in ``map``.
        cfg: the traffic settings.
        planner: the global planner's settings (:func:`swarm_nav.planner.plan_path`).

    Returns:
        (N, 2) the path x, y [m] in ``map`` from us to the retreat place, or ``None``.
    """
    robot_xy = np.asarray(robot_xy, dtype=float)[:2]
    tried: list[np.ndarray] = []
    for xy in retreat_candidates(costmap, robot_xy, other_xy, cfg):
        if any(np.hypot(*(xy - t)) < cfg.yield_retreat_spacing for t in tried):
            continue
        tried.append(xy)
        res = plan_path(costmap, robot_xy, xy, planner)
        if res.path is not None and path_length(res.path) <= cfg.yield_detour_factor * np.hypot(
                *(xy - robot_xy)) + cfg.yield_detour_slack:
            return res.path
        if len(tried) >= cfg.yield_retreat_tries:
            break
    return None


class YieldStep(StrEnum):
    """What a running yield asks of the navigator this tick (:meth:`Yield.step`)."""

    DRIVE = "drive"      # drive on to the retreat place: the command is the local planner's
    ARRIVED = "arrived"  # the drive just ended: plan the way back to the target, then stand
    WAIT = "wait"        # stand still until the other robot has passed
    DONE = "done"        # the other robot has passed (or the timeout): resume


@dataclass
class Yield:
    """A running yield: drive off the other robot's way, then wait until it has passed.

    The drive ends at the retreat place (within ``yield_arrive_tolerance``), after half of
    ``yield_timeout``, or when the local planner finds no motion for ``stuck_time``; in the last
    case, if the robot has not got ``_NO_RETREAT`` from ``start``, the yield is over at once (a
    robot packed in among others that waited where it stood only kept them packed: why:
    docs/design/navigator.md#yield). The wait ends when the path ahead has been clear for
    ``yield_clear_time`` and the robot waited at least ``yield_min_wait``, or at the latest
    ``yield_timeout`` after the yield began.

    Attributes:
        target: (2,) the retreat place x, y [m] in ``map``.
        t0: when the yield began [s].
        other: (2,) the other robot's estimated centre [m] when it began.
        phase, t_phase: ``"drive"`` or ``"wait"``, and when it began [s].
        still_since: since when [s] the drive found no motion, or ``None``.
        clear_since: since when [s] the path ahead has been clear while waiting, or ``None``.
        start: (2,) where the robot was when the yield began [m], or ``None`` (not checked).
    """

    target: np.ndarray
    t0: float
    phase: str = "drive"  # "drive" | "wait"
    t_phase: float = 0.0
    still_since: float | None = None
    clear_since: float | None = None
    other: np.ndarray = field(default_factory=lambda: np.zeros(2))
    start: np.ndarray | None = None

    def step(self, robot_xy, now: float, cfg: TrafficConfig, stuck_time: float,
             drive: Callable[[], tuple[float, float, bool]], blocked: Callable[[], bool]
             ) -> tuple[YieldStep, float, float]:
        """One tick of the yield.

        Args:
            robot_xy: (2,) our position x, y [m] in ``map``.
            now: time [s].
            cfg: the traffic settings.
            stuck_time: the drive ends after finding no motion this long [s].
            drive: called only while driving: the local planner's command ``(v [m/s], w [rad/s],
                moving)`` along the retreat path (``moving``: the command is a motion).
            blocked: called only while waiting: whether a robot is seen on the path ahead
                (``yield_clear_distance`` of it, within ``robot_radius + yield_clear_margin``).

        Returns:
            ``(step, v, w)``: what to do, and the command [m/s, rad/s] (zero unless DRIVE).
        """
        if self.phase == "drive":
            arrived = np.hypot(*(robot_xy - self.target)) <= cfg.yield_arrive_tolerance
            if not arrived and now - self.t_phase < cfg.yield_timeout / 2:
                v, w, moving = drive()
                if moving:
                    self.still_since = None
                elif self.still_since is None:
                    self.still_since = now
                if self.still_since is None or now - self.still_since < stuck_time:
                    return YieldStep.DRIVE, v, w
                if (self.start is not None
                        and np.hypot(*(np.asarray(robot_xy) - self.start)) < _NO_RETREAT):
                    return YieldStep.DONE, 0.0, 0.0
            self.phase, self.t_phase = "wait", now
            return YieldStep.ARRIVED, 0.0, 0.0
        if blocked():
            self.clear_since = None
        elif self.clear_since is None:
            self.clear_since = now
        clear = self.clear_since is not None and now - self.clear_since >= cfg.yield_clear_time
        if ((clear and now - self.t_phase >= cfg.yield_min_wait)
                or now - self.t0 >= cfg.yield_timeout):
            return YieldStep.DONE, 0.0, 0.0
        return YieldStep.WAIT, 0.0, 0.0
