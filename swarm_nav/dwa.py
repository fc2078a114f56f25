"""The local planner: the dynamic window approach of Fox, Burgard and Thrun (1997).

Each control tick :func:`dwa_command` samples ``vx_samples x vtheta_samples`` velocity pairs from
the dynamic window (the velocities reachable within one control period under the acceleration
limits, intersected with the velocity limits), rolls each out over ``sim_time`` as an exact
circular arc (constant velocities, as Fox et al.), and keeps only the *admissible* ones: no
obstacle point ever enters the footprint box grown by ``footprint_padding`` along the rollout.
Between two checked poses no point of the box moves farther than ``step = (|v| + |w| r) dt`` (``r``
the footprint's circumscribed radius), so the gap may dip at most ``step / 2`` below the checked
values; that much is added to the padding, which makes the check hold along the whole continuous
arc. A rollout lasts at least one control period plus the time to brake (``sim_time`` = 1.7 s, 0.44
m at full speed, is far more than the 0.1 s + 0.1 s and 1.4 cm the waffle needs), so an admissible
command always leaves room to stop: Fox et al.'s admissibility condition. The admissible pair of
least weighted cost wins; the critics (DWB's names) are

- ``PathDist``: distance [m] from the rollout's end to the nearest point of the local path;
- ``GoalDist``: distance [m] from the rollout's end to the lookahead point (``lookahead_dist``
  along the path, or the path's end when nearer), which rewards progress;
- ``PathAlign``: heading error [rad] at the rollout's end toward the lookahead point;
- ``BaseObstacle``: ``((influence - gap) / influence)^2`` for the smallest gap [m] between the
  footprint and the obstacle points along the rollout (0 beyond ``influence_distance``);
- ``Speed``: ``(max_vel_x - v) / max_vel_x``, Fox et al.'s velocity term.

Collision checks are cheap first: a distance transform of the obstacle points on a local 2.5 cm
grid gives, for every rollout pose, a lower bound of its distance to the nearest point; only poses
that bound cannot clear are checked exactly against the points (the footprint box's signed
Chebyshev gap, a lower bound of the Euclidean gap, so the check is conservative), candidate by
candidate in order of cost until one is admissible.

The samples form a grid of ``vx x vtheta`` pairs and a rollout's headings depend on its rotational
speed alone, so headings and their sines and cosines are computed once per ``vtheta`` sample and
shared by all ``vx`` samples (the same floating-point values as computing them per rollout).  The
loops over rollout poses and points are compiled (:mod:`swarm_nav.dwa_kernels`): a call is three
compiled calls with numpy's ``cos``, ``sin`` and ``arctan2`` between them, and gives the same
answers to the last bit as the numpy expressions they replaced (``tests/swarm_nav/
test_dwa_equivalence.py`` checks them against the first implementation).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from swarm_common.geometry import Path2D, Points2D, wrap_angle
from swarm_nav import dwa_kernels as kernels
from swarm_nav.config import DwaConfig

_GRID = 0.025  # [m/cell] resolution of the local distance grid


@dataclass(frozen=True)
class Footprint:
    """The robot's footprint as a box in ``base_footprint`` (the bounding box of its polygon).

    Attributes:
        x_min, x_max: rear and front edges [m].
        y_min, y_max: right and left edges [m].
    """

    x_min: float
    x_max: float
    y_min: float
    y_max: float

    @classmethod
    def from_polygon(cls, polygon) -> Footprint:
        """The bounding box of a (K, 2) footprint polygon x, y [m] in ``base_footprint``."""
        poly = np.asarray(polygon, dtype=float).reshape(-1, 2)
        if len(poly) < 3:
            raise ValueError("footprint: need a polygon of at least 3 points")
        return cls(*(float(v) for v in (poly[:, 0].min(), poly[:, 0].max(),
                                         poly[:, 1].min(), poly[:, 1].max())))

    @property
    def centre(self) -> tuple[float, float]:
        """(x, y) [m] of the box centre in ``base_footprint``."""
        return 0.5 * (self.x_min + self.x_max), 0.5 * (self.y_min + self.y_max)

    @property
    def half_size(self) -> tuple[float, float]:
        """(hx, hy) [m] half length and half width of the box."""
        return 0.5 * (self.x_max - self.x_min), 0.5 * (self.y_max - self.y_min)

    @property
    def radius(self) -> float:
        """Circumscribed radius [m] of the box about ``base_footprint`` (what rotating sweeps)."""
        xs = (self.x_min, self.x_max)
        ys = (self.y_min, self.y_max)
        return max(math.hypot(x, y) for x in xs for y in ys)

    def polygon(self) -> np.ndarray:
        """(4, 2) corners x, y [m] in ``base_footprint``, counter-clockwise."""
        return np.array([[self.x_min, self.y_min], [self.x_max, self.y_min],
                         [self.x_max, self.y_max], [self.x_min, self.y_max]])


@dataclass(frozen=True)
class RobotState:
    """The robot as the local planner sees it.

    Attributes:
        pose: (3,) x [m], y [m], yaw [rad] in ``map``.
        v, w: current forward [m/s] and rotational [rad/s] speeds.
    """

    pose: np.ndarray
    v: float
    w: float


@dataclass(frozen=True)
class Command:
    """The local planner's answer.

    Attributes:
        v, w: forward [m/s] and rotational [rad/s] speeds to command.
        ok: False when no admissible motion was found (``v`` is 0 and ``w`` is 0 or a rotation in
            place that was checked to be safe).
        cost: the chosen rollout's weighted cost (``inf`` when not ``ok``).
        min_gap: smallest gap [m] between the footprint and an obstacle along the chosen rollout
            (``inf`` without obstacles nearby).
        trajectory: (T, 3) poses x, y, yaw in ``map`` of the chosen rollout, or ``None``.
    """

    v: float
    w: float
    ok: bool
    cost: float = math.inf
    min_gap: float = math.inf
    trajectory: np.ndarray | None = None


def dynamic_window(state: RobotState, cfg: DwaConfig, dt: float) -> tuple[float, float, float,
                                                                          float]:
    """The velocities reachable within one control period (Fox et al. 1997, V_d intersect V_s).

    Args:
        state: the current speeds ``v`` [m/s] and ``w`` [rad/s].
        cfg: velocity limits, ``acc_lim_*`` and ``decel_lim_*`` [m/s^2, rad/s^2].
        dt: the control period [s].

    Returns:
        ``(v_min, v_max, w_min, w_max)`` in [m/s] and [rad/s]; never empty (a speed outside the
        limits is brought back toward them as fast as the limits allow).
    """
    v, w = float(state.v), float(state.w)
    v_lo = max(cfg.min_vel_x, v - abs(cfg.decel_lim_x) * dt)
    v_hi = min(cfg.max_vel_x, v + cfg.acc_lim_x * dt)
    if v_lo > v_hi:  # outside the limits: move toward them
        v_lo = v_hi = min(max(v, cfg.min_vel_x), cfg.max_vel_x)
    dw = max(cfg.acc_lim_theta, abs(cfg.decel_lim_theta)) * dt
    w_lo = max(-cfg.max_vel_theta, w - dw)
    w_hi = min(cfg.max_vel_theta, w + dw)
    if w_lo > w_hi:
        w_lo = w_hi = min(max(w, -cfg.max_vel_theta), cfg.max_vel_theta)
    return v_lo, v_hi, w_lo, w_hi


def footprint_gaps(x, y, yaw, points: Points2D, footprint: Footprint) -> np.ndarray:
    """Signed gap [m] between the footprint box at each pose and the nearest obstacle point.

    The gap to a point is ``max(|qx| - hx, |qy| - hy)`` with ``q`` the point in the box's frame:
    exact inside the box (minus the penetration depth), a lower bound of the Euclidean distance
    outside (exact except toward the corners).

    Args:
        x, y, yaw: (...) poses x, y [m] in ``map`` and yaw [rad].
        points: (M, 2) obstacle points x, y [m] in ``map``.
        footprint: the footprint box.

    Returns:
        (...) the smallest gap [m] over the points; ``inf`` without points.
    """
    x = np.asarray(x, dtype=float)
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return np.full(x.shape, np.inf)
    yaw = np.asarray(yaw, dtype=float)
    c, s = np.cos(yaw), np.sin(yaw)
    bx, by = _box_centres(x, np.asarray(y, dtype=float), c, s, footprint)
    hx, hy = footprint.half_size
    c, s = c[..., None], s[..., None]
    dx = pts[:, 0] - bx[..., None]
    dy = pts[:, 1] - by[..., None]
    return np.maximum(np.abs(c * dx + s * dy) - hx, np.abs(c * dy - s * dx) - hy).min(axis=-1)


def _box_centres(x, y, c, s, footprint: Footprint) -> tuple[np.ndarray, np.ndarray]:
    """Centres x, y [m] in ``map`` of the box at poses x, y with ``c, s`` = cos, sin of the yaw
    (all of one shape, or broadcasting)."""
    cx, cy = footprint.centre
    return x + c * cx - s * cy, y + s * cx + c * cy


def point_gaps(pose, points: Points2D, footprint: Footprint) -> np.ndarray:
    """(M,) signed gap [m] between the footprint box at one pose and each point.

    The per-point form of :func:`footprint_gaps` (same Chebyshev gap: exact inside the box, a
    lower bound of the Euclidean distance outside).

    Args:
        pose: (3,) x [m], y [m], yaw [rad] in ``map``.
        points: (M, 2) x, y [m] in ``map``.
        footprint: the footprint box.
    """
    pts = np.asarray(points, dtype=float).reshape(-1, 2)
    yaw = float(pose[2])
    c, s = float(np.cos(yaw)), float(np.sin(yaw))
    bx, by = _box_centres(float(pose[0]), float(pose[1]), c, s, footprint)
    hx, hy = footprint.half_size
    dx = pts[:, 0] - bx
    dy = pts[:, 1] - by
    return np.maximum(np.abs(c * dx + s * dy) - hx, np.abs(c * dy - s * dx) - hy)


def dwa_command(state: RobotState, path: Path2D, obstacles: Points2D, cfg: DwaConfig, *,
                footprint: Footprint, dt: float) -> Command:
    """Choose the velocity command for the next control period.

    Args:
        state: the robot's pose in ``map`` and current speeds.
        path: (N, 2) x, y [m] in ``map``, the local stretch of the global path the robot follows,
            starting near the robot; its last point is where the robot stops when it is nearer
            than ``lookahead_dist``.
        obstacles: (M, 2) obstacle points x, y [m] in ``map`` (the scan's end points, plus static
            map points if wanted); points farther than the rollouts can reach are ignored.
        cfg: the DWA settings.
        footprint: the robot's footprint box.
        dt: the control period [s] over which the window is reachable.

    Returns:
        The :class:`Command` of least cost among admissible rollouts.  When the robot already is
        nearer than ``footprint_padding`` to a point, a rollout is admissible if it never gets
        nearer than it is; when none is admissible, ``ok`` is False and the command is a safe
        rotation in place toward the path, or a stop.
    """
    pose = np.asarray(state.pose, dtype=float).reshape(3)
    path = np.asarray(path, dtype=float).reshape(-1, 2)
    if len(path) == 0:
        raise ValueError("dwa_command: empty path")
    v_lo, v_hi, w_lo, w_hi = dynamic_window(state, cfg, dt)
    vs = linspace(v_lo, v_hi, cfg.vx_samples) if v_hi > v_lo else np.array([v_lo])
    ws = linspace(w_lo, w_hi, cfg.vtheta_samples) if w_hi > w_lo else np.array([w_lo])
    if w_lo < 0.0 < w_hi and not (ws == 0.0).any():
        ws = np.append(ws, 0.0)  # always offer driving straight
    reach_v = max(abs(v_lo), abs(v_hi))
    reach_w = max(abs(w_lo), abs(w_hi))
    # the rollout must cover one period plus the braking distance (Fox et al.'s admissibility)
    horizon = max(cfg.sim_time, dt + reach_v / abs(cfg.decel_lim_x))
    n = max(1, math.ceil(reach_v * horizon / cfg.sim_granularity),
            math.ceil(reach_w * horizon / cfg.angular_sim_granularity))
    x0, y0, th0 = (float(c) for c in pose)
    cx, cy = footprint.centre
    hx, hy = footprint.half_size
    # rollout k has vs[k // len(ws)], ws[k % len(ws)]; its headings are those of ws[k % len(ws)]
    times, th, px, py, gap_now = kernels.window_setup(
        x0, y0, th0, ws, horizon, n, np.asarray(obstacles, dtype=float).reshape(-1, 2),
        reach_v * horizon + footprint.radius + cfg.footprint_padding + 2 * _GRID,
        float(np.cos(th0)), float(np.sin(th0)), cx, cy, hx, hy)
    need = min(cfg.footprint_padding, gap_now)
    cos_th, sin_th = np.cos(th), np.sin(th)
    path_x, path_y = np.ascontiguousarray(path[:, 0]), np.ascontiguousarray(path[:, 1])
    # between two checked poses no point of the box moves more than `step`, so the gap can dip
    # at most half of it below the checked values: each rollout must keep that much more than
    # `need` (a continuous guarantee)
    (x, y, bx, by, need_s, lower, upper_min, est_min, unsure, to_path, i0, carrot_x, carrot_y,
     ty, tx, has_tangent, end_dx, end_dy) = kernels.rollouts_and_bounds(
        x0, y0, math.sin(th0), math.cos(th0), vs, ws, times, cos_th, sin_th, cx, cy,
        footprint.radius, horizon / n, need, px, py, _GRID, math.hypot(hx, hy), min(hx, hy),
        path_x, path_y, cfg.lookahead_dist)
    tangent = math.atan2(ty, tx) if has_tangent else 0.0
    aim = np.arctan2(end_dy, end_dx)  # rollout end -> carrot

    # score; then check the candidates exactly in order of cost: the first admissible wins
    cost, best, min_gap = kernels.choose(
        x, y, aim, th, vs, ws, x0, y0, carrot_x, carrot_y, tangent, path_x, path_y, to_path, i0,
        est_min, upper_min, need_s, cfg.max_vel_x, cfg.obstacle_influence, _scales(cfg), lower,
        unsure, bx, by, cos_th, sin_th, px, py, hx, hy)
    if best >= 0:
        traj = np.column_stack((x[best], y[best], wrap_angle(th[best % len(ws)])))
        return Command(float(vs[best // len(ws)]), float(ws[best % len(ws)]), True,
                       float(cost[best]), float(min_gap), traj)
    return _fallback(pose, np.array([carrot_x, carrot_y]), tangent, np.column_stack((px, py)),
                     footprint, cfg, (w_lo, w_hi))


def rotation_is_safe(pose, angle: float, obstacles: Points2D, footprint: Footprint,
                     padding: float, step: float = 0.1) -> bool:
    """Whether rotating in place by ``angle`` [rad] keeps every obstacle point out of the box.

    Args:
        pose: (3,) x [m], y [m], yaw [rad] in ``map``.
        angle: signed rotation [rad].
        obstacles: (M, 2) points x, y [m] in ``map``.
        footprint: the footprint box.
        padding: the safety margin [m]; a robot already nearer may rotate if it gets no nearer.
        step: angular step [rad] between checks.

    Returns:
        True if the rotation is collision-free.
    """
    pose = np.asarray(pose, dtype=float)
    local = _local_points(obstacles, pose, footprint.radius + padding + 0.05)
    if len(local) == 0:
        return True
    n = max(1, math.ceil(abs(angle) / step))
    yaws = pose[2] + angle * np.arange(0, n + 1) / n
    gaps = footprint_gaps(np.full(n + 1, pose[0]), np.full(n + 1, pose[1]), yaws, local,
                          footprint)
    dip = 0.5 * abs(angle) / n * footprint.radius  # what the steps may skip over
    return bool(gaps[1:].min() - dip >= min(padding, gaps[0]))


_ARANGE: dict[int, np.ndarray] = {}


def linspace(start: float, stop: float, num: int) -> np.ndarray:
    """``np.linspace(start, stop, num)`` of two floats, equal to it bit for bit, in a quarter of
    its time (the DWA samples its window with two of them every tick).

    numpy 2's own steps for scalar ends: ``arange(num) * step + start`` with ``step = (stop -
    start) / (num - 1)``, then the last element set to ``stop`` (a zero step takes numpy's own
    path).  ``tests/swarm_nav/test_dwa.py`` holds it against ``np.linspace``.

    Args:
        start: first value.
        stop: last value.
        num: number of values (>= 2).

    Returns:
        (num,) float64 array.
    """
    if num < 2:
        return np.linspace(start, stop, num)
    step = (stop - start) / (num - 1)
    if step == 0.0:
        return np.linspace(start, stop, num)
    ramp = _ARANGE.get(num)
    if ramp is None:
        ramp = _ARANGE[num] = np.arange(num, dtype=float)
    out = ramp * step
    out += start
    out[-1] = stop
    return out


def _local_points(obstacles: Points2D, pose: np.ndarray, radius: float) -> np.ndarray:
    pts = np.asarray(obstacles, dtype=float).reshape(-1, 2)
    if len(pts) == 0:
        return pts
    d2 = (pts[:, 0] - pose[0]) ** 2 + (pts[:, 1] - pose[1]) ** 2
    return pts[d2 <= radius * radius]


_SCALES: dict[DwaConfig, np.ndarray] = {}


def _scales(cfg: DwaConfig) -> np.ndarray:
    """(5,) the critics' weights: PathDist, GoalDist, PathAlign, BaseObstacle, Speed."""
    scales = _SCALES.get(cfg)
    if scales is None:
        scales = _SCALES[cfg] = np.array([cfg.path_dist_scale, cfg.goal_dist_scale,
                                          cfg.path_align_scale, cfg.obstacle_scale,
                                          cfg.speed_scale])
    return scales


def _fallback(pose, carrot, tangent, local, footprint: Footprint, cfg: DwaConfig,
              w_window: tuple[float, float]) -> Command:
    """No admissible motion: rotate in place toward the path if that is safe (within the
    rotational window), else stop."""
    d = carrot - pose[:2]
    aim = math.atan2(d[1], d[0]) if np.hypot(*d) > 0.15 else tangent
    err = wrap_angle(aim - pose[2])
    sign = 1.0 if err >= 0 else -1.0
    for direction in (sign, -sign):
        w = float(np.clip(direction * min(cfg.max_vel_theta, 0.5), *w_window))
        if w * direction > 0 and rotation_is_safe(pose, direction * 0.5, local, footprint,
                                                  cfg.footprint_padding):
            return Command(0.0, w, False)
    return Command(0.0, 0.0, False)  # brake as hard as the robot can
