"""The whole navigator of one robot as a pure state machine: the ROS node only wires it up.

:class:`NavigatorCore` owns the costmap, the global path
(:class:`~swarm_nav.tracking.PathTracker`), what the robot sees
(:class:`~swarm_nav.perception.ObstacleSet`), the local planner, the holding pattern
(:class:`~swarm_nav.holding_behaviour.HoldingBehaviour`) and the recoveries. The node calls
:meth:`~NavigatorCore.set_map` once, :meth:`~NavigatorCore.on_scan` with each scan's end points in
``map``, :meth:`~NavigatorCore.step` once per control tick with the robot's pose and speeds, and
publishes :attr:`~NavigatorCore.status` and :attr:`~NavigatorCore.path`. Nothing here talks to
another robot.

States (``NavState``): IDLE, PLANNING (a goal waits for its first plan), DRIVING, HOLDING (the goal
is taken: holding spot or loop), RECOVERING, SUCCEEDED, ABORTED (with the reason), CANCELED.

Per tick in DRIVING/HOLDING: goal reached? (within ``xy_goal_tolerance``, latched, then an in-place
rotation to the goal yaw) -> holding pattern (:meth:`HoldingBehaviour.step
<swarm_nav.holding_behaviour.HoldingBehaviour.step>` decides: drive on, hold, wait, replan to a
new holding point, take another workstation, or give the goal up) -> replan if the robot left
its path by more than ``max_path_deviation``, or something blocks the path ahead (a robot standing
on it for ``stationary_replan_time``, anything else for ``blocked_replan_time``; the replan then
plans around the robots seen) -> DWA on the local stretch of the path, shifted to the right while
a robot comes toward us on it (:func:`~swarm_nav.traffic.keep_right`); when it finds no motion
because a wall is at the edge of the padding, the wall escape may come to ``wall_escape_padding``
of the walls alone (:meth:`NavigatorCore._wall_escape`) -> recovery when the DWA finds no motion
for ``stuck_time`` or the progress checker fails: the face-to-face rule
(:func:`~swarm_nav.traffic.must_yield`) makes one of two robots retreat off the other's way and
wait until its path is clear (:class:`~swarm_nav.traffic.Yield`); otherwise nav2's set (replan
around the robots seen, back up, wait, spin), cycled, never giving up on a reachable goal; after
a whole cycle a robot packed in among others or against a wall (a knot) escapes in the wait's
turn (:func:`~swarm_nav.recovery.escape_command`). The other robots are known only from the scan
(:mod:`swarm_nav.perception`). Why each rule exists: docs/design/navigator.md.

Paths are planned on the static costmap plus keep-out discs about the workstations and holding
points (robots stop there, so paths to elsewhere keep to the lanes).  Plans are made only on a new
goal or holding point, a blocked path, a path left behind, or a recovery.
"""

from __future__ import annotations

import dataclasses
import hashlib
import math
from collections import OrderedDict
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from swarm_common.geometry import Path2D, Points2D, Pose2D, wrap_angle
from swarm_common.nav_status import TERMINAL, TOOK_ANOTHER, NavState
from swarm_nav import core_kernels
from swarm_nav.config import CostmapConfig, NavigatorConfig
from swarm_nav.costmap import Costmap, add_keepout, build_costmap, overlay_obstacles
from swarm_nav.dwa import (
    Command,
    Footprint,
    RobotState,
    dwa_command,
    footprint_gaps,
    point_gaps,
    rotation_is_safe,
)
from swarm_nav.holding import HoldingSite
from swarm_nav.holding_behaviour import HoldingBehaviour, HoldingDecision, HoldingKind
from swarm_nav.perception import ObstacleSet, SeenRobot
from swarm_nav.planner import PlanResult, lru, plan_path
from swarm_nav.recovery import SEQUENCE, ProgressChecker, Recovery, RecoveryKind
from swarm_nav.tracking import PathTracker
from swarm_nav.traffic import (
    KEEP_RIGHT_LATERAL,
    Yield,
    YieldStep,
    keep_right,
    must_yield,
    oncoming_centres,
    plan_retreat,
    robots_ahead,
)
from swarm_scene.occupancy import OccupancyMap

_EPS = 1e-6  # [m] a goal shift below this is no shift
_WALL_NEAR = 0.03  # [m] a wall holds a robot the DWA finds no motion for if it is nearer than
#                   footprint_padding plus this (motions may dip that much between checks)
_WALL_MATCH = 0.05  # [m] a scan point this near a static map obstacle point is the wall, seen
#                    (a cell's centre to its edge is 0.025 m at 0.05 m/cell, plus 2 sigma of
#                    the lidar's 1 cm noise)


@dataclass(frozen=True)
class NavStatus:
    """A snapshot of the navigator for ``nav_status``.

    Attributes:
        state: the state.
        goal_id: the current (or last) goal's id; ``""`` before any goal.
        goal: (3,) x [m], y [m], yaw [rad] of the goal in ``map``, or ``None``.
        distance_remaining: distance [m] still to drive (along the path when it leads to the goal,
            else straight to the goal); 0 without a goal.
        navigation_time, holding_time: time [s] since the goal was accepted (frozen when it
            ended), and spent holding for it.
        recoveries: recovery behaviours run for this goal.
        reason: why the goal was aborted (or a note on success); ``""`` otherwise.
    """

    state: NavState
    goal_id: str
    goal: np.ndarray | None
    distance_remaining: float
    navigation_time: float
    recoveries: int
    holding_time: float
    reason: str


# Process-wide: the static costmaps of each map (the robots of a group process share the map; why:
# docs/design/navigator.md#shared-static-costmaps). (map digest, settings) -> costmap; the same +
# keep-out discs -> costmap.
_STATIC: OrderedDict = OrderedDict()
_STATIC_MAX = 8


def static_costmaps(occ: OccupancyMap, cfg: CostmapConfig, keepout: np.ndarray,
                    radius: float, cost: int) -> tuple[Costmap, Costmap]:
    """The static costmap of ``occ`` (:func:`~swarm_nav.costmap.build_costmap`) and the same with
    keep-out discs about ``keepout`` (:func:`~swarm_nav.costmap.add_keepout`), cached per
    process: equal inputs give the same two objects, whose arrays are read-only.

    Args:
        occ: the occupancy map.
        cfg: the costmap settings.
        keepout: (K, 2) x, y [m] in ``map`` of the keep-out discs' centres.
        radius, cost: the discs' radius [m] and cost.
    """
    data = np.ascontiguousarray(occ.data)
    h = hashlib.blake2b(data.tobytes(), digest_size=16)
    h.update(np.asarray([occ.resolution, *np.asarray(occ.origin, dtype=float).ravel(),
                         *data.shape], dtype=float).tobytes())
    key = (h.digest(), cfg)
    costmap = _cached(key, lambda: build_costmap(occ, cfg))
    pts = np.ascontiguousarray(keepout, dtype=float).reshape(-1, 2)
    planning = _cached((*key, pts.tobytes(), float(radius), int(cost)),
                       lambda: add_keepout(costmap, pts, radius, cost))
    return costmap, planning


def _cached(key, make) -> Costmap:
    def read_only():
        cm = make()
        cm.costs.flags.writeable = False
        cm.obstacle_distance.flags.writeable = False
        return cm

    return lru(_STATIC, key, read_only, _STATIC_MAX)


class NavigatorCore:
    """One robot's navigator (see the module docstring).

    Args:
        cfg: the configuration.
        footprint: (K, 2) footprint polygon x, y [m] in ``base_footprint`` (its bounding box is
            used), or a :class:`~swarm_nav.dwa.Footprint`.
        holding_sites: per workstation (pose (3,) [m, rad], holding points (K, 2) [m]) in ``map``.
        site_kinds: per workstation of ``holding_sites``, its kind
            (:func:`~swarm_nav.holding.workstation_kind`): a holding robot may take another free
            workstation of its goal's kind (``swap_range``). Empty (the default): never.

    Raises:
        ValueError: ``site_kinds`` is neither empty nor one per holding site.
    """

    def __init__(self, cfg: NavigatorConfig, footprint,
                 holding_sites: Sequence[HoldingSite] = (), site_kinds: Sequence[str] = ()):
        self.cfg = cfg
        self.footprint = (footprint if isinstance(footprint, Footprint)
                          else Footprint.from_polygon(footprint))
        self._holding = HoldingBehaviour(cfg, holding_sites, site_kinds)
        self.costmap: Costmap | None = None
        self._plan_cm: Costmap | None = None
        self._state = NavState.IDLE
        self._goal: np.ndarray | None = None
        self._goal_id = ""
        self._reason = ""
        self._t_goal = 0.0
        self._t_end: float | None = None
        self._recoveries = 0
        self._holding_time = 0.0
        self._now = 0.0
        self._last_step: float | None = None
        self._pose: np.ndarray | None = None
        self._track = PathTracker(cfg)
        self._obs = ObstacleSet(cfg, self.footprint)
        self._adjusted_goal: np.ndarray | None = None
        self._rotating = False
        self._recovery: Recovery | None = None
        # the DWA settings of _wall_escape: the walls alone, with wall_escape_padding
        self._escape_cfg = dataclasses.replace(cfg.dwa,
                                               footprint_padding=cfg.dwa.wall_escape_padding)
        self._yield: Yield | None = None
        self._recovery_next = 0
        self._progress = ProgressChecker(cfg.recovery)
        self._stuck_since: float | None = None

    # ------------------------------------------------------------------ inputs
    def set_map(self, occ: OccupancyMap) -> None:
        """Use a (new) static map; an active goal is planned again on the next step."""
        hc = self.cfg.holding
        self.costmap, self._plan_cm = static_costmaps(
            occ, self.cfg.costmap, self._holding.avoid, hc.workstation_keepout_radius,
            hc.workstation_keepout_cost)
        self._obs.costmap = self.costmap
        if self._state not in TERMINAL:
            self._track.path = None

    def set_goal(self, goal: Pose2D, goal_id: str, now: float) -> None:
        """Accept a goal, replacing the current one (RViz/nav2 "goal pose" convention).

        Args:
            goal: (3,) x [m], y [m], yaw [rad] in ``map``.
            goal_id: the goal's id, echoed in the status.
            now: time [s].
        """
        g = np.asarray(goal, dtype=float).ravel()
        self._goal = g[:3].copy() if g.size >= 3 else np.array([*g[:2], 0.0])
        self._goal_id = str(goal_id)
        self._reason = ""
        self._t_goal, self._t_end = now, None
        self._recoveries, self._holding_time, self._recovery_next = 0, 0.0, 0
        self._holding.clear()
        self._recovery = self._yield = self._adjusted_goal = self._stuck_since = None
        self._rotating = False
        self._track.path = None
        self._track.unblock()
        self._state = NavState.PLANNING
        if not np.all(np.isfinite(self._goal)):
            self._end(NavState.ABORTED, now, "goal is not finite")
            return
        if self.costmap is None:
            self._end(NavState.ABORTED, now, "no map")
            return
        if self._pose is not None:
            self._start_goal(self._pose, now)

    def cancel(self, now: float) -> None:
        """Cancel the current goal (CANCELED); nothing happens without an active goal."""
        if self._state not in TERMINAL:
            self._end(NavState.CANCELED, now, "canceled")

    def on_scan(self, points_map: Points2D, now: float) -> None:
        """Take a scan's end points.

        Args:
            points_map: (M, 2) x, y [m] in ``map`` of the returns in range (no inf/NaN).
            now: the scan's time [s].
        """
        viewer = self._pose[:2] if self._pose is not None else np.zeros(2)
        self._obs.update(points_map, viewer, now)

    # ------------------------------------------------------------------ outputs
    @property
    def state(self) -> NavState:
        """The current state."""
        return self._state

    @property
    def status_key(self) -> tuple[NavState, str, str]:
        """``(state, goal_id, reason)`` of :attr:`status`, without computing the rest (the node
        compares it every tick to decide whether to publish)."""
        return self._state, self._goal_id, self._reason

    @property
    def path(self) -> Path2D | None:
        """(N, 2) the current global path x, y [m] in ``map``, or ``None``."""
        return self._track.path

    @property
    def path_version(self) -> int:
        """Incremented whenever :attr:`path` changes (the node republishes ``plan`` then)."""
        return self._track.version

    @property
    def robots_seen(self) -> list[SeenRobot]:
        """The other robots in the last scan (centres, points, velocities) in ``map``."""
        return list(self._obs.robots)

    @property
    def swaps(self) -> int:
        """Times a holding robot took another workstation (back to the one sent counts too),
        since the navigator started."""
        return self._holding.swaps

    @property
    def status(self) -> NavStatus:
        """The current :class:`NavStatus`."""
        end = self._t_end if self._t_end is not None else self._now
        nav_time = max(0.0, end - self._t_goal) if self._goal is not None else 0.0
        return NavStatus(self._state, self._goal_id,
                         None if self._goal is None else self._goal.copy(),
                         self._distance_remaining(), nav_time, self._recoveries,
                         self._holding_time, self._reason)

    # ------------------------------------------------------------------ the tick
    def step(self, pose: Pose2D, v: float, w: float, now: float) -> tuple[float, float]:
        """One control tick.

        Args:
            pose: (3,) the robot's x [m], y [m], yaw [rad] in ``map``.
            v, w: its current forward [m/s] and rotational [rad/s] speeds.
            now: time [s].

        Returns:
            ``(v, w)``, the command [m/s, rad/s] for this tick.
        """
        pose = np.asarray(pose, dtype=float).reshape(3)
        dt = 0.0 if self._last_step is None else max(0.0, now - self._last_step)
        self._last_step = now
        self._now = now
        self._pose = pose
        if self._state == NavState.HOLDING:
            self._holding_time += dt
        if self._state in TERMINAL:
            return self._out(0.0, 0.0)
        if self._state == NavState.PLANNING:
            self._start_goal(pose, now)
            if self._state in TERMINAL:
                return self._out(0.0, 0.0)
        if self._track.path is None and not self._rotating:
            self._replan(pose, overlay=False)
            if self._state in TERMINAL:
                return self._out(0.0, 0.0)
        state = RobotState(pose, float(v), float(w))

        # goal reached: latch, then turn in place to the goal's yaw
        if not self._holding.holding and not self._rotating and self._at_goal(pose):
            self._rotating = True
            self._recovery = None
            self._state = NavState.DRIVING
        if self._rotating:
            return self._out(*self._rotate_to_goal(pose, now))

        if self._yield is not None:
            return self._out(*self._step_yield(pose, state, now))
        if self._recovery is not None:
            v_cmd, w_cmd, done = self._recovery.step(pose, self._obs.obstacles(pose, now), now)
            if not done:
                return self._out(v_cmd, w_cmd)
            self._finish_recovery(pose, now)

        decision = self._holding.step(pose, now, self.costmap, self._obs, self._track,
                                      self._holding_time,
                                      lambda a, b: self._plan(a, b, overlay=False))
        self._apply(decision, pose, now)
        if self._state in TERMINAL:  # given up (a robot died on the goal), or no plan
            return self._out(0.0, 0.0)
        if decision.kind == HoldingKind.WAIT:
            self._progress.reset(pose, now)
            self._stuck_since = None
            return self._out(0.0, 0.0)
        track = self._track
        if track.path is None:
            return self._out(0.0, 0.0)

        track.advance(pose)
        if track.deviation(pose) > self.cfg.max_path_deviation:
            self._replan(pose, overlay=False)
        elif track.blocked(self.costmap, self._obs, pose, now):
            self._replan(pose, overlay=True)
        if self._state in TERMINAL or track.path is None:
            return self._out(0.0, 0.0)

        local = track.local()
        seen, tc = self._obs.seen, self.cfg.traffic
        if len(seen.centres) and core_kernels.may_keep_right(  # (no shift: most ticks)
                seen.centres, seen.velocity, float(pose[0]), float(pose[1]), float(pose[2]),
                self.cfg.holding.moving_speed, tc.keep_right_distance, math.pi / 2,
                np.ascontiguousarray(local[:, 0]), np.ascontiguousarray(local[:, 1]),
                KEEP_RIGHT_LATERAL):
            local = keep_right(local, pose,
                               oncoming_centres(seen.centres, seen.velocity, pose[:2],
                                                self.cfg.holding.moving_speed),
                               self.costmap, tc, lateral=KEEP_RIGHT_LATERAL)
        obstacles = self._obs.obstacles(pose, now)
        cmd = dwa_command(state, local, obstacles, self.cfg.dwa, footprint=self.footprint,
                          dt=self.cfg.control_period)
        if not cmd.ok and cmd.w == 0.0:
            cmd = self._wall_escape(state, local, now) or cmd
        if self._needs_recovery(pose, cmd.ok, cmd.v, cmd.w, now):
            self._start_recovery(pose, now)
            if self._recovery is None:  # yielding instead
                return self._out(0.0, 0.0)
            v_cmd, w_cmd, done = self._recovery.step(pose, obstacles, now)
            if done:
                self._finish_recovery(pose, now)
            return self._out(v_cmd, w_cmd)
        return self._out(cmd.v, cmd.w)

    # ------------------------------------------------------------------ goal and plan
    def _apply(self, decision: HoldingDecision, pose: np.ndarray, now: float) -> None:
        """Carry out the holding behaviour's decision of this tick (:class:`HoldingKind`)."""
        kind = decision.kind
        if kind == HoldingKind.ABORT:
            self._end(NavState.ABORTED, now, decision.reason)
        elif kind == HoldingKind.NEW_GOAL:
            self._goal = decision.goal
            self._start_goal(pose, now, decision.plan)
        elif kind != HoldingKind.DRIVE or decision.replan:
            self._state = NavState.DRIVING if kind == HoldingKind.DRIVE else NavState.HOLDING
            if decision.replan:
                self._replan(pose, overlay=False)
                self._progress.reset(pose, now)

    def _start_goal(self, pose: np.ndarray, now: float, res: PlanResult | None = None) -> None:
        """Plan to the goal (or take ``res``, a plan to it already made) and start driving."""
        if res is None:
            res = self._plan(pose[:2], self._goal[:2], overlay=False)
        if res.path is None:
            self._end(NavState.ABORTED, now, res.reason)
            return
        self._adjusted_goal = res.path[-1].copy() if res.goal_shift > _EPS else None
        self._track.set(res.path, to_goal=True)
        self._holding.start(self._goal, res.path)
        self._state = NavState.DRIVING
        self._progress.reset(pose, now)

    def _plan(self, start, target, overlay: bool) -> PlanResult:
        cm = self._plan_cm
        if overlay and len(self._obs.dynamic):
            cm = overlay_obstacles(cm, self._obs.dynamic, self.cfg.costmap)
        return plan_path(cm, start, target, self.cfg.planner)

    def _target(self) -> np.ndarray:
        target = self._holding.target
        return self._goal[:2] if target is None else target

    def _replan(self, pose: np.ndarray, overlay: bool) -> None:
        """Plan from ``pose`` to the current target (around the robots seen if ``overlay``).

        On failure the old path is kept; without one, a goal is aborted with the planner's reason
        and a holding spot is replaced by the robot's own position.
        """
        target = self._target()
        to_goal = self._holding.target is None
        res = self._plan(pose[:2], target, overlay)
        if res.path is None and overlay:
            res = self._plan(pose[:2], target, overlay=False)
        self._track.unblock()
        if res.path is not None:
            self._track.set(res.path, to_goal=to_goal)
        elif not to_goal:
            self._holding.pattern.replace_target(pose[:2])
            self._track.set(np.vstack((pose[:2], pose[:2])), to_goal=False)
        elif self._track.path is None:
            self._end(NavState.ABORTED, self._now, res.reason)

    def _at_goal(self, pose: np.ndarray) -> bool:
        tol, adjusted = self.cfg.goal.xy_goal_tolerance, self._adjusted_goal
        return bool(np.hypot(*(pose[:2] - self._goal[:2])) <= tol or (
            adjusted is not None and np.hypot(*(pose[:2] - adjusted)) <= tol))

    def _rotate_to_goal(self, pose: np.ndarray, now: float) -> tuple[float, float]:
        err = wrap_angle(self._goal[2] - pose[2])
        if abs(err) <= self.cfg.goal.yaw_goal_tolerance:
            note = ""
            if np.hypot(*(pose[:2] - self._goal[:2])) > self.cfg.goal.xy_goal_tolerance:
                shift = np.hypot(*(self._adjusted_goal - self._goal[:2]))
                note = f"goal was in the inflation: reached the free spot {shift:.2f} m from it"
            sent = self._holding.sent_goal
            if (sent is not None  # another workstation (not back to the one sent)
                    and np.hypot(*(self._goal[:2] - sent[:2])) > _EPS):
                (x, y), (x0, y0) = self._goal[:2], sent[:2]
                note = "; ".join(filter(None, (
                    f"{TOOK_ANOTHER}({x:.3f}, {y:.3f}), free while the goal at "
                    f"({x0:.3f}, {y0:.3f}) was taken", note)))
            self._end(NavState.SUCCEEDED, now, note)
            return 0.0, 0.0
        decel = abs(self.cfg.dwa.decel_lim_theta)
        speed = min(self.cfg.goal.rotate_to_heading_angular_vel, self.cfg.dwa.max_vel_theta,
                    math.sqrt(2.0 * decel * abs(err)))
        speed = max(speed, self.cfg.goal.min_rotate_to_heading_angular_vel)
        obstacles = self._obs.obstacles(pose, now)
        check = self.cfg.goal.rotate_to_heading_check_angle
        for sign in (math.copysign(1.0, err), -math.copysign(1.0, err)):
            if rotation_is_safe(pose, sign * min(check, abs(err)), obstacles, self.footprint,
                                self.cfg.dwa.footprint_padding):
                return 0.0, sign * speed
        return 0.0, 0.0

    def _end(self, state: NavState, now: float, reason: str) -> None:
        if state == NavState.SUCCEEDED:
            self._holding.reached(self._goal)
        self._state, self._reason, self._t_end = state, reason, now
        self._recovery = self._yield = None
        self._rotating = False

    # ------------------------------------------------------------------ local planning
    def _wall_escape(self, state: RobotState, local: np.ndarray, now: float) -> Command | None:
        """A motion out of a wall's padding when the DWA found none; ``None`` if there is none
        or it is not a wall that holds the robot.

        A robot stopped parallel to a wall at the edge of ``footprint_padding`` can neither
        turn (a corner swings nearer the wall) nor drive (its heading is a degree toward it), so
        the DWA refuses every motion (why: docs/design/navigator.md#wall-escape). Here the DWA
        runs again against the walls alone -- the static map's obstacle points near the robot and
        the scan points within ``_WALL_MATCH`` of them -- with ``wall_escape_padding``; its
        motion is taken only if it keeps the usual rule against every other point, seen or
        predicted: no nearer than ``min(footprint_padding, its gap now)`` along the whole
        rollout.
        """
        pose = state.pose
        pad = self.cfg.dwa.footprint_padding
        reach = self.footprint.radius + pad + self.cfg.dwa.max_vel_x * self.cfg.dwa.sim_time
        static = self._obs.static_near(pose)
        static = static[np.hypot(static[:, 0] - pose[0], static[:, 1] - pose[1]) < reach]
        if not len(static) or point_gaps(pose, static, self.footprint).min() >= pad + _WALL_NEAR:
            return None
        scan = self._obs.scan
        scan = scan[np.hypot(scan[:, 0] - pose[0], scan[:, 1] - pose[1]) < reach]
        d = np.hypot(scan[:, None, 0] - static[None, :, 0], scan[:, None, 1] - static[None, :, 1])
        on_wall = d.min(axis=1) < _WALL_MATCH if len(scan) else np.zeros(0, dtype=bool)
        others = np.vstack((scan[~on_wall], self._obs.predicted(pose, now)))
        cmd = dwa_command(state, local, np.vstack((static, scan[on_wall])), self._escape_cfg,
                          footprint=self.footprint, dt=self.cfg.control_period)
        if cmd.v == 0.0 and cmd.w == 0.0:
            return None
        if not len(others):
            return dataclasses.replace(cmd, ok=True)
        need = min(pad, float(point_gaps(pose, others, self.footprint).min()))
        if cmd.trajectory is None:  # the fallback: a rotation in place
            if not rotation_is_safe(pose, math.copysign(0.5, cmd.w), others, self.footprint, pad):
                return None
        else:
            traj = np.vstack((pose, cmd.trajectory))
            steps = (np.hypot(*np.diff(traj[:, :2], axis=0).T)
                     + np.abs(np.diff(np.unwrap(traj[:, 2]))) * self.footprint.radius)
            gaps = footprint_gaps(traj[1:, 0], traj[1:, 1], traj[1:, 2], others, self.footprint)
            if (gaps - steps / 2.0).min() < need:
                return None
        return dataclasses.replace(cmd, ok=True)

    # ------------------------------------------------------------------ recovery
    def _needs_recovery(self, pose, ok: bool, v: float, w: float, now: float) -> bool:
        rc = self.cfg.recovery
        still = not ok or (abs(v) < rc.still_vel_x and abs(w) < rc.still_vel_theta)
        if still:
            if self._stuck_since is None:
                self._stuck_since = now
        else:
            self._stuck_since = None
        stuck = self._stuck_since is not None and now - self._stuck_since >= rc.stuck_time
        progressing = self._progress.check(pose, now)
        return stuck or not progressing

    def _start_recovery(self, pose: np.ndarray, now: float) -> None:
        tc = self.cfg.traffic
        kind = SEQUENCE[self._recovery_next % len(SEQUENCE)]
        self._recovery_next += 1
        # a knot: packed in among robots, a whole cycle has not freed us; waiting cannot help,
        # widening our smallest gap can (recovery.escape_command; docs/design/navigator.md#knots)
        if (kind == RecoveryKind.WAIT and self._recovery_next > len(SEQUENCE)
                and self._packed(pose)):
            self._begin_recovery(RecoveryKind.ESCAPE, pose, now)
            return
        # a face-to-face deadlock: the robot the rule picks gets out of the way and waits; once a
        # whole cycle of recoveries has not freed the robot, a robot beside or behind it counts
        # too (two robots side by side, heading opposite ways along a wall, each blocked by the
        # other: docs/design/navigator.md#yield)
        cone = math.pi / 3 if self._recovery_next <= len(SEQUENCE) else math.pi
        centres = self._obs.seen.centres
        ahead = robots_ahead(pose, centres, tc.deadlock_distance, half_angle=cone)
        if len(ahead):
            other = centres[ahead[0]]
            if must_yield(pose[:2], other, tc.yield_axis_angle) and self._begin_yield(
                    pose, other, now):
                return
        self._begin_recovery(kind, pose, now)
        if kind == RecoveryKind.REPLAN:
            self._replan(pose, overlay=True)

    def _begin_recovery(self, kind: RecoveryKind, pose: np.ndarray, now: float) -> None:
        spin_sign = 1.0
        if self._track.path is not None:
            tgt = self._track.spin_target() - pose[:2]
            spin_sign = 1.0 if wrap_angle(math.atan2(tgt[1], tgt[0]) - pose[2]) >= 0 else -1.0
        self._recovery = Recovery(kind, pose, now, self.cfg.recovery, self.footprint,
                                  self.cfg.dwa.footprint_padding, self.cfg.robot_index, spin_sign)
        self._recoveries += 1
        self._state = NavState.RECOVERING
        self._stuck_since = None

    def _packed(self, pose: np.ndarray) -> bool:
        """Whether another robot or a wall is nearer to our footprint than ``escape_clearance``
        (a wall counts too: docs/design/navigator.md#knots)."""
        pts = np.vstack((self._obs.dynamic, self._obs.static_near(pose)))
        if not len(pts):
            return False
        gap = footprint_gaps(pose[0], pose[1], pose[2], pts, self.footprint)
        return bool(gap < self.cfg.recovery.escape_clearance)

    def _begin_yield(self, pose: np.ndarray, other: np.ndarray, now: float) -> bool:
        """Plan a retreat off the other robot's way; False if there is none."""
        cm = self.costmap
        if len(self._obs.dynamic):
            cm = overlay_obstacles(cm, self._obs.dynamic, self.cfg.costmap)
        path = plan_retreat(cm, pose[:2], other, self.cfg.traffic, self.cfg.planner)
        if path is None:
            return False
        self._yield = Yield(path[-1].copy(), now, t_phase=now, other=other.copy(),
                            start=pose[:2].copy())
        self._track.set(path, to_goal=False)
        self._recoveries += 1
        self._state = NavState.RECOVERING
        self._stuck_since = None
        return True

    def _step_yield(self, pose: np.ndarray, state: RobotState, now: float
                    ) -> tuple[float, float]:
        y = self._yield
        rc, tc = self.cfg.recovery, self.cfg.traffic

        def drive() -> tuple[float, float, bool]:
            self._track.advance(pose)
            cmd = dwa_command(state, self._track.local(), self._obs.obstacles(pose, now),
                              self.cfg.dwa, footprint=self.footprint, dt=self.cfg.control_period)
            moving = cmd.ok and (abs(cmd.v) >= rc.still_vel_x or abs(cmd.w) >= rc.still_vel_theta)
            return cmd.v, cmd.w, moving

        def blocked() -> bool:
            return bool(len(self._track.robots_on(
                self._obs, pose, tc.yield_clear_distance,
                self.cfg.costmap.robot_radius + tc.yield_clear_margin, now)))

        step, v, w = y.step(pose[:2], now, tc, rc.stuck_time, drive, blocked)
        if step == YieldStep.DRIVE:
            return v, w
        if step == YieldStep.ARRIVED:
            self._yield = None  # plan the way back to the target, then keep waiting
            self._replan(pose, overlay=False)
            self._yield = y
        elif step == YieldStep.DONE:
            self._yield = None
            if y.phase == "drive":  # the retreat could not start: back to the target's path
                self._replan(pose, overlay=False)
            self._resume(pose, now)
        return 0.0, 0.0

    def _finish_recovery(self, pose: np.ndarray, now: float) -> None:
        kind = self._recovery.kind
        self._recovery = None
        self._resume(pose, now)
        if kind in (RecoveryKind.BACKUP, RecoveryKind.ESCAPE):
            self._replan(pose, overlay=False)

    def _resume(self, pose: np.ndarray, now: float) -> None:
        """Back from RECOVERING to HOLDING or DRIVING after a recovery or a yield; the progress
        checker and the stuck timer start afresh."""
        if self._state == NavState.RECOVERING:
            self._state = NavState.HOLDING if self._holding.holding else NavState.DRIVING
        self._progress.reset(pose, now)
        self._stuck_since = None

    # ------------------------------------------------------------------ helpers
    def _distance_remaining(self) -> float:
        if self._goal is None or self._state == NavState.SUCCEEDED or self._pose is None:
            return 0.0
        if self._track.path is not None and self._track.to_goal:
            return self._track.remaining(self._pose)
        return float(np.hypot(*(self._goal[:2] - self._pose[:2])))

    def _out(self, v: float, w: float) -> tuple[float, float]:
        return float(v), float(w)
