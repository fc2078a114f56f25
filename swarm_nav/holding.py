"""What a holding robot judges from its own scan: is the goal taken, and where to hold.

No communication: a robot judges its goal from the other robots it sees in its own scan
(:func:`swarm_nav.perception.perceive`: clusters of the points the static map does not
explain, with their velocities). The goal is occupied when a robot has enough points in the disc
of ``goal_occupied_radius`` about it and is not seen leaving. First come, first served among robots
that see each other: a robot yields when it sees another robot within ``yield_radius`` of its goal,
nearer to it by ``yield_margin`` and driving toward it (that one came first). A robot that merely
stands or passes near the goal is no reason to yield, so two robots that swap places do not wait
for each other. A queue is a reason: ``crowd_limit`` robots standing near the goal, all nearer
to it than we are and not waiting on another workstation or its holding spot
(:func:`goal_crowded`), and we hold as if it were taken. So is a queue on the
way there: ``congestion_limit`` robots standing on the path ahead in a narrow place
(:func:`path_congested`).

Where to hold: a workstation's holding spot (one point) or loop (points driven in order) comes
from the world's points of interest (:func:`holding_points_for`); a goal that is no workstation
holds ``holding_distance`` back along its path. A robot whose holding spot is taken too, or that
holds back from a congested way, waits at a staging point (:func:`staging_point`) well away from
the busy workstation, the other robots and every dock, so queues do not block the lanes or the
robot that must leave.

These are pure judgements; the holding pattern that acts on them (the state machine, the
decisions of each tick) is :mod:`swarm_nav.holding_behaviour`. Why each rule exists:
docs/design/navigator.md.
"""

from __future__ import annotations

import math
import re
from collections.abc import Sequence

import numpy as np

from swarm_common.geometry import Path2D
from swarm_nav.config import HoldingConfig
from swarm_nav.costmap import LETHAL, Costmap, segment_max_cost
from swarm_nav.perception import SeenRobot

HoldingSite = tuple[np.ndarray, np.ndarray]
"""(docking pose (3,) x, y [m], yaw [rad] in ``map``, holding points (K, 2) x, y [m])."""


def holding_sites_from_poi(poi) -> list[HoldingSite]:
    """The holding sites of a world's points of interest, as :class:`NavigatorCore` takes them.

    Args:
        poi: a ``swarm_scene.poi.PointsOfInterest`` (anything with ``workstations`` whose items
            have ``pose`` (3,) and ``holding`` (K, 2)), or ``None``.

    Returns:
        One (pose (3,), holding points (K, 2)) per workstation, in ``map`` [m, rad].
    """
    if poi is None:
        return []
    return [(np.asarray(w.pose, dtype=float).copy(),
             np.asarray(w.holding, dtype=float).reshape(-1, 2).copy())
            for w in poi.workstations]


def workstation_kind(name: str) -> str:
    """The kind of a workstation: its name without a trailing number and separator
    (``"loader3"`` and ``"loader_12"`` are ``"loader"``; ``"packing"`` is ``"packing"``).

    Workstations of one kind are interchangeable: a holding robot may take another free one of
    its goal's kind instead (``swap_range``). Our convention, for worlds whose points of interest
    number workstations that do the same job.
    """
    return re.sub(r"[\s_-]*\d+$", "", str(name)) or str(name)


def site_kinds_from_poi(poi) -> list[str]:
    """The :func:`workstation_kind` of each workstation of a world's points of interest, in the
    order of :func:`holding_sites_from_poi`; ``[]`` for ``None``."""
    if poi is None:
        return []
    return [workstation_kind(w.name) for w in poi.workstations]


def _toward(robot: SeenRobot, goal_xy: np.ndarray) -> float:
    """Speed [m/s] of a robot toward the goal (negative: away); NaN if unknown."""
    d = goal_xy - robot.centre
    n = float(np.hypot(*d))
    if n < 1e-6:
        return 0.0
    return float(robot.velocity @ d / n)


def goal_occupied(robots: Sequence[SeenRobot], goal_xy, cfg: HoldingConfig) -> bool:
    """Whether another robot stands on the goal (or is driving onto it, and not off it).

    Args:
        robots: the robots seen (:func:`~swarm_nav.perception.perceive`).
        goal_xy: (2,) the goal x, y [m].
        cfg: ``goal_occupied_radius`` [m], ``goal_occupied_min_points``, ``moving_speed`` [m/s].

    Returns:
        True if some robot has at least ``goal_occupied_min_points`` points within the radius and
        is not seen leaving it faster than ``moving_speed``.
    """
    g = np.asarray(goal_xy, dtype=float)[:2]
    for r in robots:
        d = np.hypot(r.points[:, 0] - g[0], r.points[:, 1] - g[1])
        if int((d <= cfg.goal_occupied_radius).sum()) < cfg.goal_occupied_min_points:
            continue
        toward = _toward(r, g)
        if not (toward < -cfg.moving_speed):  # NaN (unknown) counts as staying
            return True
    return False


def someone_came_first(robots: Sequence[SeenRobot], robot_xy, goal_xy,
                       cfg: HoldingConfig) -> bool:
    """First come, first served: another robot heading for our goal and nearer to it than we are.

    Args:
        robots: the robots seen (:func:`~swarm_nav.perception.perceive`).
        robot_xy, goal_xy: (2,) our position and the goal, x, y [m].
        cfg: ``yield_radius`` [m], ``yield_margin`` [m] and ``moving_speed`` [m/s].

    Returns:
        True if some robot within ``yield_radius`` of the goal, nearer to it than we are by more
        than ``yield_margin``, is seen driving toward it faster than ``moving_speed``.
    """
    g = np.asarray(goal_xy, dtype=float)[:2]
    mine = float(np.hypot(*(np.asarray(robot_xy, dtype=float)[:2] - g)))
    for r in robots:
        theirs = float(np.hypot(*(r.centre - g)))
        if theirs <= cfg.yield_radius and theirs + cfg.yield_margin < mine:
            if _toward(r, g) > cfg.moving_speed:
                return True
    return False


def goal_crowded(robots: Sequence[SeenRobot], robot_xy, goal_xy, cfg: HoldingConfig,
                 elsewhere=None) -> bool:
    """A queue at the goal already: ``crowd_limit`` robots stand near it, all nearer than we are.

    A free workstation that robots stand around is no free way in: they wait for it, or are
    stuck there, and the robot that must leave it needs room; robots that join such a queue
    lock it up. A robot that sees the queue holds instead, as when the goal is taken; the
    nearest ``crowd_limit`` robots keep trying, so a free goal is always tried by someone. A
    robot standing on *another* workstation or on another workstation's holding spot
    (``elsewhere``) waits for that one, not in our queue, and does not count (why:
    docs/design/navigator.md#queue-rule).

    Args:
        robots: the robots seen (:func:`~swarm_nav.perception.perceive`).
        robot_xy, goal_xy: (2,) our position and the goal, x, y [m].
        cfg: ``crowd_radius`` [m], ``crowd_limit``, ``moving_speed`` [m/s] and
            ``holding_arrive_tolerance`` [m].
        elsewhere: (J, 2) x, y [m] of the other workstations and their holding points (not the
            goal's own), or None; a robot centred within ``holding_arrive_tolerance`` of one of
            them does not count.

    Returns:
        True if at least ``crowd_limit`` robots, each centred within ``crowd_radius`` of the goal
        and nearer to it than we are, and not on a point of ``elsewhere``, are seen standing
        (slower than ``moving_speed``; unknown speed counts as standing). Never with
        ``crowd_limit`` 0.
    """
    if cfg.crowd_limit <= 0:
        return False
    g = np.asarray(goal_xy, dtype=float)[:2]
    mine = float(np.hypot(*(np.asarray(robot_xy, dtype=float)[:2] - g)))
    other = (np.zeros((0, 2)) if elsewhere is None
             else np.asarray(elsewhere, dtype=float).reshape(-1, 2))
    n = 0
    for r in robots:
        theirs = float(np.hypot(*(r.centre - g)))
        if theirs <= cfg.crowd_radius and theirs < mine:
            if len(other) and float(np.hypot(*(other - r.centre).T).min()) <= (
                    cfg.holding_arrive_tolerance):
                continue  # waiting for another workstation
            speed = float(np.hypot(*r.velocity))
            n += not (speed > cfg.moving_speed)  # NaN (unknown) counts as standing
    return n >= cfg.crowd_limit


def path_congested(centres: np.ndarray, standing: np.ndarray, ahead: np.ndarray, goal_xy,
                   avoid: np.ndarray, wall_distance: np.ndarray, cfg: HoldingConfig,
                   limit: int | None = None) -> bool:
    """A queue on the way: ``congestion_limit`` robots stand on the path ahead in a narrow place.

    A robot that drives on into robots standing in a corridor cannot pass them and closes the
    way back for those that must leave (why: docs/design/navigator.md#congestion). A robot that
    sees such a queue ahead holds back in the open (:func:`staging_point`) and tries again
    later, so the queue can drain. Robots standing in the open (``staging_wall_clearance`` or
    more from every wall) are passed around by the planner and do not count; nor do robots on a
    workstation or a holding spot (they are where they should be, off the lane), nor the last
    ``crowd_radius`` of the path, where :func:`goal_crowded` judges the queue for the goal
    itself.

    Args:
        centres: (K, 2) centres x, y [m] of the robots seen, in ``map``.
        standing: (K,) whether each is seen standing (slower than ``moving_speed``, or unknown).
        ahead: (N, 2) the next ``congestion_distance`` of our path x, y [m].
        goal_xy: (2,) the goal x, y [m].
        avoid: (J, 2) docking poses and holding points x, y [m].
        wall_distance: (K,) distance [m] of each centre from the nearest wall (static map).
        cfg: ``congestion_radius`` [m], ``congestion_limit``, ``crowd_radius`` [m],
            ``holding_arrive_tolerance`` [m] and ``staging_wall_clearance`` [m].
        limit: the number of robots that make a queue, instead of ``cfg.congestion_limit``.

    Returns:
        True if at least ``congestion_limit`` (``limit``) such robots, each centred within
        ``congestion_radius`` of that part of the path, are seen standing. Never with
        ``congestion_limit`` (``limit``) 0.
    """
    limit = cfg.congestion_limit if limit is None else limit
    if limit <= 0 or len(centres) < limit:
        return False
    centres = np.asarray(centres, dtype=float).reshape(-1, 2)
    ahead = np.asarray(ahead, dtype=float).reshape(-1, 2)
    g = np.asarray(goal_xy, dtype=float)[:2]
    ahead = ahead[np.hypot(*(ahead - g).T) > cfg.crowd_radius]
    if not len(ahead):
        return False
    cand = (np.asarray(standing, dtype=bool)
            & (np.asarray(wall_distance, dtype=float) < cfg.staging_wall_clearance))
    avoid = np.asarray(avoid, dtype=float).reshape(-1, 2)
    if len(avoid):
        da = np.hypot(centres[:, None, 0] - avoid[None, :, 0],
                      centres[:, None, 1] - avoid[None, :, 1])
        cand &= da.min(axis=1) > cfg.holding_arrive_tolerance
    if int(cand.sum()) < limit:
        return False
    c = centres[cand]
    d = np.hypot(c[:, None, 0] - ahead[None, :, 0], c[:, None, 1] - ahead[None, :, 1])
    return int((d.min(axis=1) <= cfg.congestion_radius).sum()) >= limit


def goal_visible(costmap: Costmap, robot_xy, goal_xy, cfg: HoldingConfig) -> bool:
    """Whether the robot can judge its goal: within ``goal_detection_range``, no wall between."""
    robot_xy = np.asarray(robot_xy, dtype=float)[:2]
    goal_xy = np.asarray(goal_xy, dtype=float)[:2]
    if np.hypot(*(goal_xy - robot_xy)) > cfg.goal_detection_range:
        return False
    return segment_max_cost(costmap, robot_xy, goal_xy) < LETHAL


def goal_site(goal, sites: Sequence[HoldingSite], cfg: HoldingConfig,
              with_points: bool = False) -> int | None:
    """The index of the goal's own workstation: the nearest site within
    ``workstation_match_radius`` of the goal.

    Args:
        goal: (2,) or (3,) the goal in ``map`` [m, rad].
        sites: the workstations' holding data, each (pose (3,), points (K, 2)) in ``map``.
        cfg: ``workstation_match_radius`` [m].
        with_points: only sites that have holding points count.

    Returns:
        The index into ``sites``, or None when no (such) site is that near.
    """
    g = np.asarray(goal, dtype=float).ravel()[:2]
    best, best_d = None, math.inf
    for i, (pose, pts) in enumerate(sites):
        d = float(np.hypot(*(np.asarray(pose, dtype=float)[:2] - g)))
        if (d <= cfg.workstation_match_radius and d < best_d
                and (not with_points or np.asarray(pts).size > 0)):
            best, best_d = i, d
    return best


def holding_points_for(goal, sites: Sequence[HoldingSite], path: Path2D | None,
                       cfg: HoldingConfig) -> tuple[np.ndarray, bool]:
    """Where a robot holds while its goal is taken.

    Args:
        goal: (2,) or (3,) the goal in ``map`` [m, rad].
        sites: the workstations' holding data, each (pose (3,), points (K, 2)) in ``map``.
        path: (N, 2) the path to the goal, or ``None``.
        cfg: ``workstation_match_radius`` [m] and ``holding_distance`` [m].

    Returns:
        ``(points, loop)``: (K, 2) x, y [m] and whether they are a loop driven in order (K >= 2) or
        a single spot.  A goal that is no workstation (or one without holding points) holds at the
        point ``holding_distance`` back along its path (the path's start when shorter, the goal
        itself without a path).
    """
    g = np.asarray(goal, dtype=float).ravel()[:2]
    i = goal_site(g, sites, cfg, with_points=True)
    if i is not None:
        best = np.asarray(sites[i][1], dtype=float).reshape(-1, 2)
        return best.copy(), len(best) >= 2
    if path is None or len(path) < 2:
        return g[None, :].copy(), False
    rev = np.asarray(path, dtype=float)[::-1]
    s = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(rev, axis=0).T))))
    x = np.interp(cfg.holding_distance, s, rev[:, 0])
    y = np.interp(cfg.holding_distance, s, rev[:, 1])
    return np.array([[x, y]]), False


def staging_point(costmap: Costmap, goal_xy, robot_xy, centres: np.ndarray,
                  avoid: np.ndarray, cfg: HoldingConfig, step: float = 0.25) -> np.ndarray | None:
    """A place to wait out of the way when the goal's holding spot is taken too.

    Robots queueing for a busy workstation must not crowd it (the robot that leaves it needs a
    way out) nor fill the lane to the others.  A staging point is the centre of a cell on a
    ``step`` lattice within ``staging_search_radius`` of the robot that is free of inflation cost
    (at least the inflation radius from walls), at least ``staging_distance`` from the goal,
    ``staging_clearance`` from every robot seen and ``workstation_clearance`` from every
    workstation and holding point, and reachable; the one nearest the robot wins.  Where some
    such place is also ``staging_wall_clearance`` from every wall, only those count: a robot
    waiting in a corridor narrows the lane the others drive through, and a few of them stop its
    two-way traffic (why: docs/design/navigator.md#staging-points-and-making-room).

    Args:
        costmap: the static costmap.
        goal_xy: (2,) the goal x, y [m] in ``map``.
        robot_xy: (2,) the robot's x, y [m].
        centres: (K, 2) centres [m] of the robots seen.
        avoid: (J, 2) docking poses and holding points x, y [m] to keep clear of.
        cfg: the holding settings.
        step: lattice spacing [m] of the candidates.

    Returns:
        (2,) x, y [m], or ``None`` when no place qualifies.
    """
    robot_xy = np.asarray(robot_xy, dtype=float)[:2]
    goal_xy = np.asarray(goal_xy, dtype=float)[:2]
    r = cfg.staging_search_radius
    g = np.arange(-r, r + 1e-9, step)
    cand = robot_xy + np.stack(np.meshgrid(g, g), axis=-1).reshape(-1, 2)
    cand = cand[np.hypot(*(cand - robot_xy).T) <= r]
    ok = (costmap.cost_at(cand) == 0) & (np.hypot(*(cand - goal_xy).T) >= cfg.staging_distance)
    for pts, clearance in ((centres, cfg.staging_clearance), (avoid, cfg.workstation_clearance)):
        pts = np.asarray(pts, dtype=float).reshape(-1, 2)
        if len(pts) and ok.any():
            d = np.hypot(cand[:, None, 0] - pts[None, :, 0], cand[:, None, 1] - pts[None, :, 1])
            ok &= d.min(axis=1) >= clearance
    rc = costmap.world_to_cell(robot_xy)
    if costmap.in_bounds(rc):
        labels = costmap.components(False)
        mine = labels[rc[0], rc[1]]
        if mine:
            crc = costmap.world_to_cell(cand)
            inside = costmap.in_bounds(crc)
            same = np.zeros(len(cand), dtype=bool)
            same[inside] = labels[crc[inside, 0], crc[inside, 1]] == mine
            ok &= same
    if not ok.any():
        return None
    open_ = ok & (costmap.distance_at(cand) >= cfg.staging_wall_clearance)
    cand = cand[open_ if open_.any() else ok]
    return cand[int(np.argmin(np.hypot(*(cand - robot_xy).T)))]
