"""The whole navigator of one robot as a pure state machine: the ROS node only wires it up.

:class:`NavigatorCore` owns the costmap, the global path, the local planner, the holding pattern
and the recoveries. The node calls :meth:`~NavigatorCore.set_map` once,
:meth:`~NavigatorCore.on_scan` with each scan's end points in ``map``, :meth:`~NavigatorCore.step`
once per control tick with the robot's pose and speeds, and publishes :attr:`~NavigatorCore.status`
and :attr:`~NavigatorCore.path`. Nothing here talks to another robot.

States (``NavState``): IDLE, PLANNING (a goal waits for its first plan), DRIVING, HOLDING (the goal
is taken: holding spot or loop), RECOVERING, SUCCEEDED, ABORTED (with the reason), CANCELED.

Per tick in DRIVING/HOLDING: goal reached? (within ``xy_goal_tolerance``, latched, then an in-place
rotation to the goal yaw) -> holding pattern update (:mod:`swarm_nav.holding`) -> replan if the
robot left its path by more than ``max_path_deviation``, or something blocks the path ahead (a
robot standing on it for ``stationary_replan_time``, anything else for ``blocked_replan_time``;
the replan then plans around the robots seen) -> DWA on the local stretch of the path, shifted to
the right while a robot comes toward us on it (:func:`~swarm_nav.traffic.keep_right`); when it
finds no motion because a wall is at the edge of the padding, the wall escape may come to
``wall_escape_padding`` of the walls alone (:meth:`NavigatorCore._wall_escape`) -> recovery
when the DWA finds no motion for ``stuck_time`` or the progress checker fails: the face-to-face
rule (:func:`~swarm_nav.traffic.must_yield`) makes one of two robots retreat off the
other's way and wait until its path is clear (:class:`~swarm_nav.traffic.Yield`); otherwise
nav2's set (replan around the robots seen, back up, wait, spin), cycled, never giving up on a
reachable goal; after a whole cycle a robot packed in among others or against a wall (a knot)
escapes in the wait's turn (:func:`~swarm_nav.recovery.escape_command`). The other robots are
known only from the scan (:mod:`swarm_nav.perception`).

Paths are planned on the static costmap plus keep-out discs about the workstations and holding
points (robots stop there, so paths to elsewhere keep to the lanes).  Plans are made only on a new
goal or holding target, a blocked path, a path left behind, or a recovery.
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
from swarm_common.occupancy import OccupancyMap
from swarm_nav import core_kernels, perception_kernels
from swarm_nav.config import CostmapConfig, NavigatorConfig
from swarm_nav.costmap import INSCRIBED, Costmap, add_keepout, build_costmap, overlay_obstacles
from swarm_nav.dwa import (
    Command,
    Footprint,
    RobotState,
    dwa_command,
    footprint_gaps,
    point_gaps,
    rotation_is_safe,
)
from swarm_nav.holding import (
    HoldingPattern,
    HoldingPhase,
    HoldingSite,
    goal_crowded,
    goal_occupied,
    goal_site,
    goal_visible,
    holding_points_for,
    path_congested,
    someone_came_first,
    staging_point,
)
from swarm_nav.perception import RobotTracker, SeenArrays, SeenRobot, dynamic_points
from swarm_nav.planner import PlanResult, lru, plan_path
from swarm_nav.recovery import SEQUENCE, ProgressChecker, Recovery, RecoveryKind
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

_LOCAL_WINDOW = 3.0  # [m] of path handed to the DWA
_SEARCH_AHEAD = 40   # path points searched ahead of the progress index
_SPIN_LOOKAHEAD = 5  # path points ahead of the progress index that choose a spin's direction
_NEAR_PATH_SLACK = 0.5  # [m] robots centred farther than the checked distance plus this are
#                         not looked at for the path ahead (a cheap pre-filter)
_EPS = 1e-6  # [m] a goal shift below this is no shift
_STATIC_MARGIN = 0.5  # [m] the robot moves this far before its static obstacle window is renewed
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
        navigation_time: time [s] since the goal was accepted (frozen when it ended).
        recoveries: recovery behaviours run for this goal.
        holding_time: time [s] spent holding for this goal.
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


# Process-wide: the static costmaps of each map (the robots of a group process share the map;
# its 50 navigators built them 50 times at start-up, a sixth of a group's start-up CPU at 100
# robots in py-spy). (map digest, settings) -> costmap; the same + keep-out discs -> costmap.
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
        radius: the discs' radius [m].
        cost: the discs' cost.
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
        self.holding_sites = [
            (np.asarray(p, dtype=float), np.asarray(h, dtype=float).reshape(-1, 2))
            for p, h in holding_sites]
        if site_kinds and len(site_kinds) != len(self.holding_sites):
            raise ValueError(f"site_kinds: {len(site_kinds)} kinds for "
                             f"{len(self.holding_sites)} holding sites")
        self.site_kinds = [str(k) for k in site_kinds]
        avoid = [p[None, :2] for p, _ in self.holding_sites] + [h for _, h in self.holding_sites]
        self._avoid = np.vstack(avoid) if avoid else np.zeros((0, 2))
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
        self._path: np.ndarray | None = None
        self._path_s: np.ndarray | None = None
        self._path_to_goal = False
        self._path_version = 0
        self._path_lethal_key: tuple | None = None
        self._path_lethal_mask = np.zeros(0, dtype=bool)
        self._idx = 0
        self._adjusted_goal: np.ndarray | None = None
        self._rotating = False
        self._holding: HoldingPattern | None = None
        self._recovery: Recovery | None = None
        # the DWA settings of _wall_escape: the walls alone, with wall_escape_padding
        self._escape_cfg = dataclasses.replace(cfg.dwa,
                                               footprint_padding=cfg.dwa.wall_escape_padding)
        self._yield: Yield | None = None
        self._recovery_next = 0
        self._progress = ProgressChecker(cfg.recovery)
        self._stuck_since: float | None = None
        self._blocked_since: float | None = None
        self._crowded_since: float | None = None
        self._elsewhere = self._avoid  # the other workstations and spots (set per goal)
        self._occupied_since: float | None = None
        self._congestion_judged = -math.inf  # the scan time of the last congestion judgement
        self._swap_judged = -math.inf  # the scan time of the last look for another workstation
        self._sent_goal: np.ndarray | None = None  # the goal as set, before any swap
        self._last_site: int | None = None  # the holding site of the last goal reached
        self.swaps = 0
        """Times a holding robot took another workstation (back to the one sent counts too),
        since the navigator started."""
        self._reached_goal = False  # a goal reached since the navigator started
        self._scan = np.zeros((0, 2))
        self._dyn = np.zeros((0, 2))
        self._robots: list[SeenRobot] = []
        self._seen = SeenArrays.of([])
        self._centres = self._seen.centres
        self._movers = self._moving_points()
        self._tracker = RobotTracker(cfg.perception)
        self._scan_time = -math.inf
        self._static_superset = np.zeros((0, 2))  # boundary points near _static_centre
        self._static_centre: np.ndarray | None = None
        self._static_source: np.ndarray | None = None  # the boundary array it was taken from

    # ------------------------------------------------------------------ inputs
    def set_map(self, occ: OccupancyMap) -> None:
        """Use a (new) static map; an active goal is planned again on the next step."""
        hc = self.cfg.holding
        self.costmap, self._plan_cm = static_costmaps(
            occ, self.cfg.costmap, self._avoid, hc.workstation_keepout_radius,
            hc.workstation_keepout_cost)
        if self._state not in TERMINAL:
            self._path = None

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
        self._sent_goal = None
        self._reason = ""
        self._t_goal = now
        self._t_end = None
        self._recoveries = 0
        self._holding_time = 0.0
        self._holding = None
        self._recovery = None
        self._yield = None
        self._recovery_next = 0
        self._rotating = False
        self._adjusted_goal = None
        self._path = None
        self._stuck_since = None
        self._blocked_since = None
        self._crowded_since = None
        self._occupied_since = None
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
        pts = np.asarray(points_map, dtype=float).reshape(-1, 2)
        pts = perception_kernels.finite_rows(np.ascontiguousarray(pts))
        self._scan = pts
        self._scan_time = now
        if self.costmap is None:
            self._dyn = pts
        else:
            self._dyn = dynamic_points(pts, self.costmap,
                                       self.cfg.perception.static_point_tolerance)
        viewer = self._pose[:2] if self._pose is not None else np.zeros(2)
        self._robots, self._seen = self._tracker.update_arrays(self._dyn, viewer, now)
        self._centres = self._seen.centres
        self._movers = self._moving_points()

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
        return self._path

    @property
    def path_version(self) -> int:
        """Incremented whenever :attr:`path` changes (the node republishes ``plan`` then)."""
        return self._path_version

    @property
    def robots_seen(self) -> list[SeenRobot]:
        """The other robots in the last scan (centres, points, velocities) in ``map``."""
        return list(self._robots)

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
            v: its current forward speed [m/s].
            w: its current rotational speed [rad/s].
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
        if self._path is None and not self._rotating:
            self._replan(pose, overlay=False)
            if self._state in TERMINAL:
                return self._out(0.0, 0.0)
        state = RobotState(pose, float(v), float(w))

        # goal reached: latch, then turn in place to the goal's yaw
        if self._heading_to_goal() and not self._rotating and self._at_goal(pose):
            self._rotating = True
            self._recovery = None
            self._state = NavState.DRIVING
        if self._rotating:
            return self._out(*self._rotate_to_goal(pose, now))

        if self._yield is not None:
            return self._out(*self._step_yield(pose, state, now))
        if self._recovery is not None:
            v_cmd, w_cmd, done = self._recovery.step(pose, self._obstacles(pose), now)
            if not done:
                return self._out(v_cmd, w_cmd)
            self._finish_recovery(pose, now)

        self._update_holding(pose, now)
        if self._state in TERMINAL:  # given up: a robot died on the goal
            return self._out(0.0, 0.0)
        if self._holding is not None and self._holding.phase == HoldingPhase.WAIT:
            self._progress.reset(pose, now)
            self._stuck_since = None
            return self._out(0.0, 0.0)
        if self._path is None:
            return self._out(0.0, 0.0)

        self._advance_progress(pose)
        if self._deviation(pose) > self.cfg.max_path_deviation:
            self._replan(pose, overlay=False)
        elif self._path_blocked(now):
            self._replan(pose, overlay=True)
        if self._state in TERMINAL or self._path is None:
            return self._out(0.0, 0.0)

        local = self._local_path()
        seen, tc = self._seen, self.cfg.traffic
        if len(seen.centres) and core_kernels.may_keep_right(  # (no shift: most ticks)
                seen.centres, seen.velocity, float(pose[0]), float(pose[1]), float(pose[2]),
                self.cfg.holding.moving_speed, tc.keep_right_distance, math.pi / 2,
                np.ascontiguousarray(local[:, 0]), np.ascontiguousarray(local[:, 1]),
                KEEP_RIGHT_LATERAL):
            local = keep_right(local, pose,
                               oncoming_centres(seen.centres, seen.velocity, pose[:2],
                                                self.cfg.holding.moving_speed),
                               self.costmap, tc, lateral=KEEP_RIGHT_LATERAL)
        obstacles = self._obstacles(pose)
        cmd = dwa_command(state, local, obstacles, self.cfg.dwa, footprint=self.footprint,
                          dt=self.cfg.control_period)
        if not cmd.ok and cmd.w == 0.0:
            cmd = self._wall_escape(state, local) or cmd
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
    def _start_goal(self, pose: np.ndarray, now: float, res: PlanResult | None = None) -> None:
        """Plan to the goal (or take ``res``, a plan to it already made) and start driving."""
        if res is None:
            res = self._plan(pose[:2], self._goal[:2], overlay=False)
        if res.path is None:
            self._end(NavState.ABORTED, now, res.reason)
            return
        self._adjusted_goal = res.path[-1].copy() if res.goal_shift > _EPS else None
        self._set_path(res.path, to_goal=True)
        points, loop = holding_points_for(self._goal, self.holding_sites, res.path,
                                          self.cfg.holding)
        self._holding = HoldingPattern(points, loop, self.cfg.holding)
        self._elsewhere = self._other_sites(self._goal[:2])
        self._state = NavState.DRIVING
        self._progress.reset(pose, now)

    def _other_sites(self, goal_xy: np.ndarray) -> np.ndarray:
        """(J, 2) x, y [m] of the workstations and holding points that are not the goal's own
        (its workstation: :func:`~swarm_nav.holding.goal_site`)."""
        own = goal_site(goal_xy, self.holding_sites, self.cfg.holding)
        pts = [np.vstack((p[None, :2], h)) for i, (p, h) in enumerate(self.holding_sites)
               if i != own]
        return np.vstack(pts) if pts else np.zeros((0, 2))

    def _plan(self, start, target, overlay: bool) -> PlanResult:
        cm = self._plan_cm
        if overlay and len(self._dyn):
            cm = overlay_obstacles(cm, self._dyn, self.cfg.costmap)
        return plan_path(cm, start, target, self.cfg.planner)

    def _target(self) -> np.ndarray:
        if self._holding is not None and self._holding.target is not None:
            return self._holding.target
        return self._goal[:2]

    def _replan(self, pose: np.ndarray, overlay: bool) -> bool:
        """Plan from ``pose`` to the current target (around the robots seen if ``overlay``).

        On failure the old path is kept; without one, a goal is aborted with the planner's reason
        and a holding spot is replaced by the robot's own position.
        """
        target = self._target()
        to_goal = self._holding is None or self._holding.target is None
        res = self._plan(pose[:2], target, overlay)
        if res.path is None and overlay:
            res = self._plan(pose[:2], target, overlay=False)
        self._blocked_since = None
        if res.path is not None:
            self._set_path(res.path, to_goal=to_goal)
            return True
        if not to_goal:
            self._holding.replace_target(pose[:2])
            self._set_path(np.vstack((pose[:2], pose[:2])), to_goal=False)
        elif self._path is None:
            self._end(NavState.ABORTED, self._now, res.reason)
        return False

    def _set_path(self, path: np.ndarray, to_goal: bool) -> None:
        self._path = np.asarray(path, dtype=float)
        seg = np.hypot(*np.diff(self._path, axis=0).T) if len(self._path) > 1 else np.zeros(0)
        self._path_s = np.concatenate(([0.0], np.cumsum(seg)))
        self._path_to_goal = to_goal
        self._path_version += 1
        self._idx = 0

    def _heading_to_goal(self) -> bool:
        return self._holding is None or self._holding.phase == HoldingPhase.APPROACH

    def _at_goal(self, pose: np.ndarray) -> bool:
        tol = self.cfg.goal.xy_goal_tolerance
        if np.hypot(*(pose[:2] - self._goal[:2])) <= tol:
            return True
        if self._adjusted_goal is not None and np.hypot(*(pose[:2] - self._adjusted_goal)) <= tol:
            return True
        return False

    def _rotate_to_goal(self, pose: np.ndarray, now: float) -> tuple[float, float]:
        err = wrap_angle(self._goal[2] - pose[2])
        if abs(err) <= self.cfg.goal.yaw_goal_tolerance:
            note = ""
            if np.hypot(*(pose[:2] - self._goal[:2])) > self.cfg.goal.xy_goal_tolerance:
                shift = np.hypot(*(self._adjusted_goal - self._goal[:2]))
                note = f"goal was in the inflation: reached the free spot {shift:.2f} m from it"
            if (self._sent_goal is not None  # another workstation (not back to the one sent)
                    and np.hypot(*(self._goal[:2] - self._sent_goal[:2])) > _EPS):
                (x, y), (x0, y0) = self._goal[:2], self._sent_goal[:2]
                note = "; ".join(filter(None, (
                    f"{TOOK_ANOTHER}({x:.3f}, {y:.3f}), free while the goal at "
                    f"({x0:.3f}, {y0:.3f}) was taken", note)))
            self._end(NavState.SUCCEEDED, now, note)
            return 0.0, 0.0
        decel = abs(self.cfg.dwa.decel_lim_theta)
        speed = min(self.cfg.goal.rotate_to_heading_angular_vel, self.cfg.dwa.max_vel_theta,
                    math.sqrt(2.0 * decel * abs(err)))
        speed = max(speed, self.cfg.goal.min_rotate_to_heading_angular_vel)
        obstacles = self._obstacles(pose)
        check = self.cfg.goal.rotate_to_heading_check_angle
        for sign in (math.copysign(1.0, err), -math.copysign(1.0, err)):
            if rotation_is_safe(pose, sign * min(check, abs(err)), obstacles, self.footprint,
                                self.cfg.dwa.footprint_padding):
                return 0.0, sign * speed
        return 0.0, 0.0

    def _end(self, state: NavState, now: float, reason: str) -> None:
        if state == NavState.SUCCEEDED:
            self._reached_goal = True
            self._last_site = goal_site(self._goal[:2], self.holding_sites, self.cfg.holding)
        self._state = state
        self._reason = reason
        self._t_end = now
        self._recovery = None
        self._yield = None
        self._rotating = False

    # ------------------------------------------------------------------ holding
    def _update_holding(self, pose: np.ndarray, now: float) -> None:
        hp = self._holding
        if hp is None or self.costmap is None:
            return
        before_phase, before_target = hp.phase, hp.target
        occupied = None
        first = False
        goal = self._goal[:2]
        fresh = now - self._scan_time <= self.cfg.scan_max_age
        if fresh and goal_visible(self.costmap, pose[:2], goal, self.cfg.holding):
            occupied = goal_occupied(self._robots, goal, self.cfg.holding)
            first = (someone_came_first(self._robots, pose[:2], goal, self.cfg.holding)
                     or goal_crowded(self._robots, pose[:2], goal, self.cfg.holding,
                                     self._elsewhere))
        if self._occupant_stays(occupied, goal, now):
            timeout = self.cfg.holding.occupied_timeout
            self._end(NavState.ABORTED, now, f"goal occupied by a robot that has not moved for "
                      f"{timeout:g} s")
            return
        hp.update(now, pose[:2], occupied, first)
        if (hp.phase != HoldingPhase.APPROACH and fresh and not hp.held_back(now)
                and self._swap_judged < self._scan_time and self._take_another(pose, now)):
            return
        if self._way_congested(hp, now):
            hc = self.cfg.holding
            wait = hc.congestion_wait * (1.0 + 0.25 * (self.cfg.robot_index % 5))
            hp.hold_back(self._staging(pose), now, wait)
        # never park on top of another robot: a taken loop point is skipped, a taken spot is
        # replaced by a staging point well away from the busy workstation
        tgt = hp.target
        if (hp.phase == HoldingPhase.TO_HOLD and fresh
                and np.hypot(*(tgt - pose[:2])) < self.cfg.holding.holding_target_check_range):
            if goal_occupied(self._robots, tgt, self.cfg.holding):
                if hp.loop:
                    hp.advance()
                else:
                    hp.replace_target(self._staging(pose))
        self._make_room(hp, pose, now)
        if hp.phase == HoldingPhase.APPROACH:
            if before_phase != HoldingPhase.APPROACH:
                self._state = NavState.DRIVING
                self._replan(pose, overlay=False)
                self._progress.reset(pose, now)
            return
        self._state = NavState.HOLDING if self._recovery is None else NavState.RECOVERING
        moved = before_target is None or not np.allclose(before_target, hp.target)
        if moved:
            self._replan(pose, overlay=False)
            self._progress.reset(pose, now)

    def _take_another(self, pose: np.ndarray, now: float) -> bool:
        """While holding for a workstation, take another one of its kind instead, if one is free.

        Judged once per fresh scan, when not held back by congestion: the nearest workstation of
        the goal's kind (:attr:`site_kinds`), other than the goal's own and the one of the last
        goal reached (the robot would only go back where it came from), within ``swap_range`` of
        the robot and in line of sight, that no robot stands on or drives onto, that no nearer
        robot is heading for, and where no robots queue (the judgements made for the goal itself:
        :func:`~swarm_nav.holding.goal_occupied`, :func:`~swarm_nav.holding.someone_came_first`,
        :func:`~swarm_nav.holding.goal_crowded`). The goal becomes that workstation's docking pose
        (``nav_status`` reports it; the goal id stays), the holding pattern starts afresh for it.
        Our design (SPEC §5 has the robot hold until its own goal is free): at 100 robots in
        slim_blockage, a robot that reached the loaders' corridor no longer leaves it without a
        task while the loader beside its own is free (README "Long shifts").

        Returns:
            True if the goal changed.
        """
        hc = self.cfg.holding
        self._swap_judged = self._scan_time
        if hc.swap_range <= 0 or not self.site_kinds:
            return False
        own = goal_site(self._goal[:2], self.holding_sites, hc)
        if own is None:
            return False
        best, best_d = None, math.inf
        for i, (p, _h) in enumerate(self.holding_sites):
            if i in (own, self._last_site) or self.site_kinds[i] != self.site_kinds[own]:
                continue
            d = float(np.hypot(*(p[:2] - pose[:2])))
            if d > hc.swap_range or d >= best_d:
                continue
            if (not goal_visible(self.costmap, pose[:2], p[:2], hc)
                    or goal_occupied(self._robots, p[:2], hc)
                    or someone_came_first(self._robots, pose[:2], p[:2], hc)
                    or goal_crowded(self._robots, pose[:2], p[:2], hc, self._other_sites(p[:2]))):
                continue
            best, best_d = i, d
        if best is None:
            return False
        res = self._plan(pose[:2], self.holding_sites[best][0][:2], overlay=False)
        if res.path is None:
            return False
        self.swaps += 1
        if self._sent_goal is None:
            self._sent_goal = self._goal.copy()
        self._goal = self.holding_sites[best][0][:3].copy()
        self._occupied_since = None
        self._start_goal(pose, now, res)
        return True

    def _occupant_stays(self, occupied: bool | None, goal: np.ndarray, now: float) -> bool:
        """Whether the goal has been seen taken for ``occupied_timeout`` by a robot that does not
        move: at every judgement in that time the goal was in sight and taken, and no robot was
        seen moving (faster than ``moving_speed``) within 2 x ``goal_occupied_radius`` of it. A
        queue at a workstation moves whenever a robot docks or leaves; a robot that died on it
        never does. The goal is then unreachable, and given up (SPEC §5: aborted with the
        reason) rather than held for ever.

        Args:
            occupied: this tick's judgement (None: not judged, out of sight or no fresh scan).
            goal: (2,) x, y [m] in ``map``.
            now: time [s].
        """
        hc = self.cfg.holding
        seen = self._seen
        moving = seen.known & (seen.speed > hc.moving_speed)
        near = np.hypot(*(seen.centres - goal).T) <= 2.0 * hc.goal_occupied_radius
        if not occupied or bool((moving & near).any()):
            self._occupied_since = None
            return False
        if self._occupied_since is None:
            self._occupied_since = now
        return hc.occupied_timeout > 0 and now - self._occupied_since >= hc.occupied_timeout

    def _way_congested(self, hp: HoldingPattern, now: float) -> bool:
        """Whether the way to the goal (or to its holding spot) is congested
        (:func:`~swarm_nav.holding.path_congested`), judged once per scan while driving there.

        A starving robot (``starvation_time`` > 0; 300 s by default: one that has reached no
        goal since the navigator started and has held ``starvation_time`` for this goal) is held
        back only by a longer queue, ``starvation_congestion_limit`` robots (6; 0: by none).
        The rule keeps robots out of a crowded corridor, and at 100 robots on slim_blockage it
        kept some out for good: 12 robots had reached no goal after 30 minutes (seed 0). With
        300 s alone, 6 had, but the tasks fell from 527 to 484 and the last 10-minute window to
        0.82 of the mean; with taking another free workstation (``swap_range``) too, it is the
        default (README, "Long shifts"). Held back by nothing, the starving robots flooded the
        corridor on seed 1: from 700 to 1,200 s 8 to 12 of them were in it at once, 38 to 49
        robots in all against 16 to 24 before 600 s, and it locked up (530 tasks, the last
        window 146)."""
        hc = self.cfg.holding
        limit = hc.congestion_limit
        if (hc.starvation_time > 0 and not self._reached_goal
                and self._holding_time >= hc.starvation_time):
            limit = hc.starvation_congestion_limit
        if (hc.congestion_limit <= 0 or limit <= 0 or self._path is None or hp.rerouted
                or hp.phase == HoldingPhase.WAIT or self._scan_time <= self._congestion_judged
                or now - self._scan_time > self.cfg.scan_max_age):
            return False
        self._congestion_judged = self._scan_time
        seen = self._seen
        if len(seen.centres) < limit:
            return False
        s0 = self._path_s[self._idx]
        hi = int(np.searchsorted(self._path_s, s0 + hc.congestion_distance))
        ahead = self._path[self._idx:max(hi, self._idx + 1)]
        standing = ~(seen.known & (seen.speed > hc.moving_speed))
        return path_congested(seen.centres, standing, ahead, self._path[-1], self._avoid,
                              self.costmap.distance_at(seen.centres), hc, limit)

    def _staging(self, pose: np.ndarray) -> np.ndarray:
        """A staging point away from the goal and the robots seen (or where the robot is)."""
        xy = staging_point(self.costmap, self._goal[:2], pose[:2], self._centres,
                           self._avoid, self.cfg.holding)
        return pose[:2].copy() if xy is None else xy

    def _make_room(self, hp: HoldingPattern, pose: np.ndarray, now: float) -> None:
        """A waiting robot that another robot stays close to moves away to a staging point."""
        hc = self.cfg.holding
        close = len(self._centres) and bool(
            np.hypot(*(self._centres - pose[:2]).T).min() < hc.make_room_distance)
        if hp.phase != HoldingPhase.WAIT or not close:
            self._crowded_since = None
            return
        if self._crowded_since is None:
            self._crowded_since = now
        elif now - self._crowded_since >= hc.make_room_time:
            self._crowded_since = None
            hp.relocate(self._staging(pose), now)

    # ------------------------------------------------------------------ path following
    def _advance_progress(self, pose: np.ndarray) -> None:
        hi = min(len(self._path), self._idx + _SEARCH_AHEAD)
        d = np.hypot(*(self._path[self._idx:hi] - pose[:2]).T)
        self._idx += int(np.argmin(d))

    def _deviation(self, pose: np.ndarray) -> float:
        return float(np.hypot(*(self._path[self._idx] - pose[:2])))

    def _local_path(self) -> np.ndarray:
        s0 = self._path_s[self._idx]
        hi = int(np.searchsorted(self._path_s, s0 + _LOCAL_WINDOW, side="right"))
        return self._path[self._idx:max(hi, self._idx + 1)]

    def _path_blocked(self, now: float) -> bool:
        """Whether to replan around what blocks the path ahead: a cell of the static costmap
        at once; a robot seen standing on it after ``stationary_replan_time``; anything else
        seen on it after ``blocked_replan_time``."""
        s0 = self._path_s[self._idx]
        hi = int(np.searchsorted(self._path_s, s0 + self.cfg.blocked_check_distance))
        ahead = self._path[self._idx:max(hi, self._idx + 1)]
        if len(ahead) > 1 and self._path_lethal()[self._idx + 1:self._idx + len(ahead)].any():
            return True
        blockers = self._robots_on_path(self.cfg.blocked_check_distance,
                                        self.cfg.costmap.robot_radius, now)
        if not len(blockers):
            self._blocked_since = None
            return False
        if self._blocked_since is None:
            self._blocked_since = now
        seen = self._seen
        standing = bool((seen.known[blockers]
                         & (seen.speed[blockers] < self.cfg.holding.moving_speed)).any())
        wait = self.cfg.stationary_replan_time if standing else self.cfg.blocked_replan_time
        return now - self._blocked_since >= wait

    def _path_lethal(self) -> np.ndarray:
        """(N,) whether each path point lies in an inscribed or lethal cell of the static
        costmap (kept per path and costmap)."""
        key = self._path_lethal_key
        if key is None or key[0] != self._path_version or key[1] is not self.costmap:
            self._path_lethal_mask = self.costmap.cost_at(self._path) >= INSCRIBED
            self._path_lethal_key = (self._path_version, self.costmap)
        return self._path_lethal_mask

    def _robots_on_path(self, distance: float, radius: float, now: float) -> np.ndarray:
        """(J,) indices of the robots seen with a point within ``radius`` of the next
        ``distance`` of path (all robots' points checked at once)."""
        seen = self._seen
        if (self._path is None or not len(seen.centres)
                or now - self._scan_time > self.cfg.scan_max_age):
            return np.zeros(0, dtype=int)
        s0 = self._path_s[self._idx]
        hi = int(np.searchsorted(self._path_s, s0 + distance))
        ahead = self._path[self._idx:max(hi, self._idx + 1)]
        return core_kernels.robots_near_path(
            seen.centres, seen.points, seen.starts, seen.sizes, np.ascontiguousarray(ahead[:, 0]),
            np.ascontiguousarray(ahead[:, 1]), float(self._pose[0]), float(self._pose[1]),
            distance + _NEAR_PATH_SLACK, radius)

    def _dynamic_on_path(self, distance: float, radius: float, now: float) -> bool:
        """Whether a robot seen has a point within ``radius`` of the next ``distance`` of path."""
        return bool(len(self._robots_on_path(distance, radius, now)))

    def _obstacles(self, pose: np.ndarray) -> np.ndarray:
        """Scan points plus the static map's obstacle boundary near the robot, plus where the
        robots seen moving will be shortly."""
        parts = [self._scan, self._static_near(pose), self._predicted(pose)]
        parts = [p for p in parts if len(p)]
        return np.vstack(parts) if parts else np.zeros((0, 2))

    def _predicted(self, pose: np.ndarray) -> np.ndarray:
        """(P, 2) where the points of the robots seen moving will be shortly, x, y [m] in
        ``map``."""
        # Robots seen moving: also where they will be shortly (the scan is up to a period old).
        # A predicted point already within the padding of where we stand is left out: DWA relaxes
        # its padding to the current gap when the robot already is that near (so that it can
        # leave a tight spot), and a point that is only a guess must not relax it against the
        # points that are really there (a collision at 100 robots; tests/swarm_nav/test_core.py).
        # All robots' predictions are checked in one point_gaps call (it is per point).
        lag = max(0.0, self._now - self._scan_time)
        step = self.cfg.prediction_step
        taus = [min(tau, self.cfg.prediction_max) for tau in (lag + step, lag + 2.0 * step)]
        points, velocity, later = self._movers
        if not len(points):
            return np.zeros((0, 2))
        ahead = points + velocity * np.where(later, taus[1], taus[0])[:, None]
        return ahead[point_gaps(pose, ahead, self.footprint) >= self.cfg.dwa.footprint_padding]

    def _wall_escape(self, state: RobotState, local: np.ndarray) -> Command | None:
        """A motion out of a wall's padding when the DWA found none; ``None`` if there is none
        or it is not a wall that holds the robot.

        A robot stopped parallel to a wall at the edge of ``footprint_padding`` can neither
        turn (a corner swings nearer the wall) nor drive (its heading is a degree toward it), so
        the DWA refuses every motion: one stood 742 s so in a 20-robot shift, and a jam of 11
        robots grew around it. Here the DWA runs again against the walls alone -- the static
        map's obstacle points near the robot and the scan points within ``_WALL_MATCH`` of them
        -- with ``wall_escape_padding``; its motion is taken only if it keeps the usual rule
        against every other point, seen or predicted: no nearer than ``min(footprint_padding,
        its gap now)`` along the whole rollout.
        """
        pose = state.pose
        pad = self.cfg.dwa.footprint_padding
        reach = self.footprint.radius + pad + self.cfg.dwa.max_vel_x * self.cfg.dwa.sim_time
        static = self._static_near(pose)
        static = static[np.hypot(static[:, 0] - pose[0], static[:, 1] - pose[1]) < reach]
        if not len(static) or point_gaps(pose, static, self.footprint).min() >= pad + _WALL_NEAR:
            return None
        scan = self._scan
        scan = scan[np.hypot(scan[:, 0] - pose[0], scan[:, 1] - pose[1]) < reach]
        d = np.hypot(scan[:, None, 0] - static[None, :, 0], scan[:, None, 1] - static[None, :, 1])
        on_wall = d.min(axis=1) < _WALL_MATCH if len(scan) else np.zeros(0, dtype=bool)
        others = np.vstack((scan[~on_wall], self._predicted(pose)))
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

    def _moving_points(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The points of the robots seen moving faster than ``moving_speed``, each robot's twice
        (for the two prediction times of :meth:`_obstacles`): (P, 2) points x, y [m] in ``map``,
        (P, 2) their robot's velocity [m/s], (P,) whether the point is for the later time."""
        seen = self._seen
        moving = seen.known & (seen.speed > self.cfg.holding.moving_speed)
        # robot after robot: its points for the earlier time, then for the later one
        return perception_kernels.moving_points(seen.points, seen.starts, seen.sizes,
                                                seen.velocity, moving)

    def _static_near(self, pose: np.ndarray) -> np.ndarray:
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
        c = self._static_centre
        if (self._static_source is not stat or c is None
                or abs(pose[0] - c[0]) > _STATIC_MARGIN or abs(pose[1] - c[1]) > _STATIC_MARGIN):
            grown = r + _STATIC_MARGIN + _EPS  # _EPS: no rounding at the edge can drop a point
            m = (np.abs(stat[:, 0] - pose[0]) < grown) & (np.abs(stat[:, 1] - pose[1]) < grown)
            self._static_superset = stat[m]
            self._static_centre = pose[:2].copy()
            self._static_source = stat
        near = self._static_superset
        m = (np.abs(near[:, 0] - pose[0]) < r) & (np.abs(near[:, 1] - pose[1]) < r)
        return near[m]

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
        # widening our smallest gap can (recovery.escape_command)
        if (kind == RecoveryKind.WAIT and self._recovery_next > len(SEQUENCE)
                and self._packed(pose)):
            self._begin_recovery(RecoveryKind.ESCAPE, pose, now)
            return
        # a face-to-face deadlock: the robot the rule picks gets out of the way and waits; once a
        # whole cycle of recoveries has not freed the robot, a robot beside or behind it counts
        # too (two robots side by side, heading opposite ways along a wall, each blocked by the
        # other, recovered for over 1,000 s in a 20-robot run)
        cone = math.pi / 3 if self._recovery_next <= len(SEQUENCE) else math.pi
        ahead = robots_ahead(pose, self._centres, tc.deadlock_distance, half_angle=cone)
        if len(ahead):
            other = self._centres[ahead[0]]
            if must_yield(pose[:2], other, tc.yield_axis_angle) and self._begin_yield(
                    pose, other, now):
                return
        self._begin_recovery(kind, pose, now)
        if kind == RecoveryKind.REPLAN:
            self._replan(pose, overlay=True)

    def _begin_recovery(self, kind: RecoveryKind, pose: np.ndarray, now: float) -> None:
        spin_sign = 1.0
        if self._path is not None:
            tgt = self._path[min(self._idx + _SPIN_LOOKAHEAD, len(self._path) - 1)] - pose[:2]
            spin_sign = 1.0 if wrap_angle(math.atan2(tgt[1], tgt[0]) - pose[2]) >= 0 else -1.0
        self._recovery = Recovery(kind, pose, now, self.cfg.recovery, self.footprint,
                                  self.cfg.dwa.footprint_padding, self.cfg.robot_index, spin_sign)
        self._recoveries += 1
        self._state = NavState.RECOVERING
        self._stuck_since = None

    def _packed(self, pose: np.ndarray) -> bool:
        """Whether another robot or a wall is nearer to our footprint than ``escape_clearance``.

        A wall counts too: a robot stopped parallel to the blockage's wall, 0.046 m from it,
        dithered between turns of +-0.017 and +-0.034 rad/s (the only motions the DWA admitted)
        and stood from 951 s to the end of a 20-robot shift (seed 1, Srobot5: 839 s of
        standstills)."""
        pts = np.vstack((self._dyn, self._static_near(pose)))
        if not len(pts):
            return False
        gap = footprint_gaps(pose[0], pose[1], pose[2], pts, self.footprint)
        return bool(gap < self.cfg.recovery.escape_clearance)

    def _begin_yield(self, pose: np.ndarray, other: np.ndarray, now: float) -> bool:
        """Plan a retreat off the other robot's way; False if there is none."""
        cm = self.costmap
        if len(self._dyn):
            cm = overlay_obstacles(cm, self._dyn, self.cfg.costmap)
        path = plan_retreat(cm, pose[:2], other, self.cfg.traffic, self.cfg.planner)
        if path is None:
            return False
        self._yield = Yield(path[-1].copy(), now, t_phase=now, other=other.copy(),
                            start=pose[:2].copy())
        self._set_path(path, to_goal=False)
        self._recoveries += 1
        self._state = NavState.RECOVERING
        self._stuck_since = None
        return True

    def _step_yield(self, pose: np.ndarray, state: RobotState, now: float
                    ) -> tuple[float, float]:
        y = self._yield
        rc, tc = self.cfg.recovery, self.cfg.traffic

        def drive() -> tuple[float, float, bool]:
            self._advance_progress(pose)
            cmd = dwa_command(state, self._local_path(), self._obstacles(pose), self.cfg.dwa,
                              footprint=self.footprint, dt=self.cfg.control_period)
            moving = cmd.ok and (abs(cmd.v) >= rc.still_vel_x or abs(cmd.w) >= rc.still_vel_theta)
            return cmd.v, cmd.w, moving

        def blocked() -> bool:
            return self._dynamic_on_path(tc.yield_clear_distance,
                                         self.cfg.costmap.robot_radius + tc.yield_clear_margin,
                                         now)

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
            holding = self._holding is not None and self._holding.phase != HoldingPhase.APPROACH
            self._state = NavState.HOLDING if holding else NavState.DRIVING
            self._progress.reset(pose, now)
            self._stuck_since = None
        return 0.0, 0.0

    def _finish_recovery(self, pose: np.ndarray, now: float) -> None:
        kind = self._recovery.kind
        self._recovery = None
        self._progress.reset(pose, now)
        self._stuck_since = None
        if self._state == NavState.RECOVERING:
            holding = self._holding is not None and self._holding.phase != HoldingPhase.APPROACH
            self._state = NavState.HOLDING if holding else NavState.DRIVING
        if kind in (RecoveryKind.BACKUP, RecoveryKind.ESCAPE):
            self._replan(pose, overlay=False)

    # ------------------------------------------------------------------ helpers
    def _distance_remaining(self) -> float:
        if self._goal is None or self._state in (NavState.SUCCEEDED,):
            return 0.0
        if self._pose is None:
            return 0.0
        if self._path is not None and self._path_to_goal and self._path_s is not None:
            i = min(self._idx, len(self._path) - 1)
            return float(np.hypot(*(self._path[i] - self._pose[:2]))
                         + self._path_s[-1] - self._path_s[i])
        return float(np.hypot(*(self._goal[:2] - self._pose[:2])))

    def _out(self, v: float, w: float) -> tuple[float, float]:
        return float(v), float(w)

