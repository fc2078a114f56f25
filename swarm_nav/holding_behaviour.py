"""The holding pattern of one navigator: what a robot does while its goal is taken.

The judgements come from :mod:`swarm_nav.holding` (is the goal taken, did someone come first,
is there a queue at it or on the way, where to wait out of the way); this module acts on them.
:class:`HoldingPattern` is the state machine of one goal::

    APPROACH --goal occupied or someone came first--> TO_HOLD
    TO_HOLD  --holding spot reached--> WAIT          (a loop: on to the next point, stays TO_HOLD)
    TO_HOLD, WAIT --goal seen free for free_confirm_time--> APPROACH
    WAIT     --retry period over and the goal out of sight--> APPROACH (go and look)
    loop     --a loop point reached, retry period over, goal out of sight--> APPROACH
    APPROACH, TO_HOLD (to the spot) --the way congested--> TO_HOLD (a staging point, held back:
             neither a free goal nor the retry period ends it before congestion_wait)

It never gives up on a goal that can be reached: a goal is retried until it is free, and given up
only when a robot that never moves stands on it (``occupied_timeout``).
:class:`HoldingBehaviour` runs it for the navigator (:mod:`swarm_nav.core`) once per tick and
returns a :class:`HoldingDecision`, the way :meth:`swarm_nav.recovery.Recovery.step` returns its
command: the rules it applies (each judged from the robot's own scan, no communication) are

- hold while the goal is taken or someone came first (:meth:`HoldingPattern.update`);
- give the goal up once a robot has stood on it for ``occupied_timeout``
  (:meth:`HoldingBehaviour._occupant_stays`);
- take another free workstation of the goal's kind (``swap_range``,
  :meth:`HoldingBehaviour._take_another`);
- hold back at a staging point while the way there is congested, with a longer queue for a
  starving robot (``congestion_limit``, ``starvation_time``,
  :meth:`HoldingBehaviour._way_congested`);
- never park on another robot: a taken loop point is skipped, a taken spot replaced by a staging
  point;
- make room: a waiting robot that another robot stays close to moves to a staging point
  (``make_room_time``).

Why each rule exists, and the runs that led to it: docs/design/navigator.md. Pure (numpy, no
ROS). Tests: tests/swarm_nav/test_holding.py, tests/swarm_nav/test_core.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from enum import StrEnum

import numpy as np

from swarm_nav.config import HoldingConfig, NavigatorConfig
from swarm_nav.costmap import Costmap
from swarm_nav.holding import (
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
from swarm_nav.perception import ObstacleSet
from swarm_nav.planner import PlanResult
from swarm_nav.tracking import PathTracker


class HoldingPhase(StrEnum):
    """Where the holding pattern is."""

    APPROACH = "approach"  # driving to the goal
    TO_HOLD = "to_hold"    # driving to a holding spot or along the loop
    WAIT = "wait"          # standing at the holding spot


class HoldingPattern:
    """The holding-pattern state machine of one goal (pure: time and observations come in).

    Args:
        points: (K, 2) holding spot (K = 1) or loop points x, y [m] in ``map``.
        loop: whether the points are a loop driven in order.
        cfg: the holding settings.
    """

    def __init__(self, points: np.ndarray, loop: bool, cfg: HoldingConfig):
        self.points = np.asarray(points, dtype=float).reshape(-1, 2)
        self.loop = bool(loop) and len(self.points) >= 2
        self.cfg = cfg
        self.phase = HoldingPhase.APPROACH
        self.index = 0
        self._free_since: float | None = None
        self._blocked_at = -math.inf
        self._phase_since = 0.0
        self._override: np.ndarray | None = None
        self._held_until = -math.inf

    @property
    def target(self) -> np.ndarray | None:
        """(2,) x, y [m] the robot should drive to while holding; ``None`` in APPROACH."""
        if self.phase == HoldingPhase.APPROACH:
            return None
        if self._override is not None:
            return self._override
        return self.points[self.index]

    def update(self, now: float, robot_xy, occupied: bool | None, came_first: bool = False
               ) -> HoldingPhase:
        """Advance the state machine by one observation.

        Args:
            now: time [s].
            robot_xy: (2,) the robot's x, y [m] in ``map``.
            occupied: whether the goal is seen occupied; ``None`` when it cannot be seen (too far
                or behind a wall).
            came_first: whether another robot near the goal came first (we yield).

        Returns:
            The phase after the update.
        """
        robot_xy = np.asarray(robot_xy, dtype=float)
        seen_blocked = occupied is True or (occupied is not None and came_first)
        seen_free = occupied is False and not came_first
        if seen_blocked:
            self._blocked_at = now
            self._free_since = None
        elif seen_free:
            self._free_since = now if self._free_since is None else self._free_since
        else:
            self._free_since = None
        free_long = (self._free_since is not None
                     and now - self._free_since >= self.cfg.free_confirm_time)
        retry_due = now - self._blocked_at >= self.cfg.holding_retry_period

        if self.phase == HoldingPhase.APPROACH:
            if seen_blocked:
                self._enter(HoldingPhase.TO_HOLD, now)
                self.index = self._nearest(robot_xy)
            return self.phase
        held = self.held_back(now)
        if free_long and not held:
            self._enter(HoldingPhase.APPROACH, now)
            return self.phase
        target = self.target
        arrived = np.hypot(*(robot_xy - target)) <= self.cfg.holding_arrive_tolerance
        if self.phase == HoldingPhase.TO_HOLD and arrived:
            if self.loop and not held:
                if retry_due and occupied is None:
                    self._enter(HoldingPhase.APPROACH, now)
                else:
                    self.advance()
            else:
                self.phase, self._phase_since = HoldingPhase.WAIT, now  # where it is
        elif self.phase == HoldingPhase.WAIT:
            waited = now - self._phase_since >= self.cfg.holding_retry_period
            if waited and retry_due and occupied is None and not held:
                self._enter(HoldingPhase.APPROACH, now)
        return self.phase

    def advance(self) -> None:
        """Go on to the next loop point (a loop), or stay (a spot)."""
        self._override = None
        if self.loop:
            self.index = (self.index + 1) % len(self.points)

    def replace_target(self, xy) -> None:
        """Hold at ``xy`` (2,) [m] instead of the spot (the spot is taken by another robot)."""
        self._override = np.asarray(xy, dtype=float).reshape(2)

    def hold_back(self, xy, now: float, wait: float) -> None:
        """Hold at ``xy`` (2,) [m] for at least ``wait`` [s] from ``now`` [s] whatever is seen of
        the goal: the way to it is congested (:func:`path_congested`), not the goal taken. The
        robot then retries as from any holding spot."""
        self._enter(HoldingPhase.TO_HOLD, now)
        self.replace_target(xy)
        self._held_until = now + max(0.0, float(wait))
        self._free_since = None

    def held_back(self, now: float) -> bool:
        """Whether a :meth:`hold_back` is still running at ``now`` [s]."""
        return now < self._held_until

    @property
    def rerouted(self) -> bool:
        """Whether the robot holds somewhere other than its holding spot or loop (a staging
        point, or where it stands)."""
        return self._override is not None

    def relocate(self, xy, now: float) -> None:
        """Move on to hold at ``xy`` (2,) [m] (from WAIT: make room for another robot)."""
        if self.phase == HoldingPhase.WAIT:
            self.phase, self._phase_since = HoldingPhase.TO_HOLD, now
        self._override = np.asarray(xy, dtype=float).reshape(2)

    def _enter(self, phase: HoldingPhase, now: float) -> None:
        self.phase = phase
        self._phase_since = now
        self._override = None
        if phase == HoldingPhase.APPROACH:
            self._free_since = None

    def _nearest(self, xy: np.ndarray) -> int:
        return int(np.argmin(np.hypot(*(self.points - xy).T)))


class HoldingKind(StrEnum):
    """What the navigator is to do after a tick of the holding behaviour."""

    DRIVE = "drive"        # drive to the goal (replan: the holding just ended, plan to it again)
    HOLD = "hold"          # drive to the holding point (replan: the point moved)
    WAIT = "wait"          # stand at the holding point (replan: as HOLD), no motion
    NEW_GOAL = "new_goal"  # another workstation was taken: ``goal``, planned as ``plan``
    ABORT = "abort"        # give the goal up, for ``reason``


@dataclass(frozen=True)
class HoldingDecision:
    """One tick's decision of :meth:`HoldingBehaviour.step`.

    Attributes:
        kind: what to do.
        replan: DRIVE, HOLD, WAIT: plan again from the robot to the target (the goal, or the
            holding point) and restart the progress checker.
        goal: NEW_GOAL: (3,) x, y [m], yaw [rad] in ``map`` of the other workstation's docking
            pose, the new goal (the goal id stays).
        plan: NEW_GOAL: the plan to it.
        reason: ABORT: why the goal is given up.
    """

    kind: HoldingKind
    replan: bool = False
    goal: np.ndarray | None = None
    plan: PlanResult | None = None
    reason: str = ""


_DRIVE = HoldingDecision(HoldingKind.DRIVE)


class HoldingBehaviour:
    """The holding pattern of one navigator, across its goals (see the module docstring).

    Args:
        cfg: the navigator's configuration (``holding``, ``scan_max_age``, ``robot_index``).
        sites: per workstation (pose (3,) [m, rad], holding points (K, 2) [m]) in ``map``.
        kinds: per workstation of ``sites``, its kind
            (:func:`~swarm_nav.holding.workstation_kind`): a holding robot may take another free
            workstation of its goal's kind (``swap_range``). Empty: never.

    Attributes:
        sites, kinds: the workstations' holding sites and their kinds.
        avoid: (J, 2) x, y [m] of every workstation and holding point (keep-out discs, staging).
        pattern: the current goal's :class:`HoldingPattern`, or ``None`` before its first plan.
        sent_goal: (3,) the goal as set, once another workstation was taken for it; else
            ``None``.
        swaps: times a holding robot took another workstation (back to the one sent counts
            too), since the navigator started.
        reached_goal: whether a goal was reached since the navigator started.

    Raises:
        ValueError: ``kinds`` is neither empty nor one per site.
    """

    def __init__(self, cfg: NavigatorConfig, sites: Sequence[HoldingSite] = (),
                 kinds: Sequence[str] = ()):
        self.cfg = cfg
        self.sites = [(np.asarray(p, dtype=float), np.asarray(h, dtype=float).reshape(-1, 2))
                      for p, h in sites]
        if kinds and len(kinds) != len(self.sites):
            raise ValueError(f"site_kinds: {len(kinds)} kinds for {len(self.sites)} holding "
                             f"sites")
        self.kinds = [str(k) for k in kinds]
        avoid = [p[None, :2] for p, _ in self.sites] + [h for _, h in self.sites]
        self.avoid = np.vstack(avoid) if avoid else np.zeros((0, 2))
        self.pattern: HoldingPattern | None = None
        self.sent_goal: np.ndarray | None = None
        self.swaps = 0
        self.reached_goal = False
        self._goal = np.zeros(3)
        self._elsewhere = self.avoid  # the other workstations and spots (set per goal)
        self._last_site: int | None = None  # the holding site of the last goal reached
        self._occupied_since: float | None = None
        self._crowded_since: float | None = None
        self._congestion_judged = -math.inf  # the scan time of the last congestion judgement
        self._swap_judged = -math.inf  # the scan time of the last look for another workstation

    # ------------------------------------------------------------------ the navigator's calls
    def clear(self) -> None:
        """A new goal was set: no pattern until it is planned, nothing taken for it yet."""
        self.pattern = None
        self.sent_goal = None
        self._crowded_since = None
        self._occupied_since = None

    def start(self, goal: np.ndarray, path: np.ndarray) -> None:
        """The goal (3,) [m, rad] was planned as ``path`` (N, 2) [m]: a fresh pattern for it."""
        self._goal = goal
        points, loop = holding_points_for(goal, self.sites, path, self.cfg.holding)
        self.pattern = HoldingPattern(points, loop, self.cfg.holding)
        self._elsewhere = self._other_sites(goal[:2])

    def reached(self, goal: np.ndarray) -> None:
        """The goal (3,) [m, rad] was reached."""
        self.reached_goal = True
        self._last_site = goal_site(goal[:2], self.sites, self.cfg.holding)

    @property
    def holding(self) -> bool:
        """Whether the robot holds (the pattern is past APPROACH)."""
        return self.pattern is not None and self.pattern.phase != HoldingPhase.APPROACH

    @property
    def target(self) -> np.ndarray | None:
        """(2,) x, y [m] to drive to while holding; ``None`` when heading for the goal."""
        return None if self.pattern is None else self.pattern.target

    def step(self, pose: np.ndarray, now: float, costmap: Costmap | None, obs: ObstacleSet,
             track: PathTracker, holding_time: float,
             plan: Callable[[np.ndarray, np.ndarray], PlanResult]) -> HoldingDecision:
        """One tick of the holding pattern.

        Args:
            pose: (3,) the robot's x [m], y [m], yaw [rad] in ``map``.
            now: time [s].
            costmap: the static costmap, or ``None`` before the map.
            obs: what the robot sees (the robots of the last scan).
            track: the path followed (the congestion rule looks along it).
            holding_time: time [s] held for this goal so far.
            plan: plans from a start (2,) to a target (2,) [m] on the planning costmap (without
                the robots seen).

        Returns:
            The :class:`HoldingDecision`.
        """
        hp, hc = self.pattern, self.cfg.holding
        if hp is None or costmap is None:
            return _DRIVE
        before_phase, before_target = hp.phase, hp.target
        occupied = None
        first = False
        goal = self._goal[:2]
        fresh = obs.fresh(now)
        # waited long enough (patience_time): the queue it sees no longer holds it
        patient = hc.patience_time <= 0 or holding_time < hc.patience_time
        if fresh and goal_visible(costmap, pose[:2], goal, hc):
            occupied = goal_occupied(obs.robots, goal, hc)
            first = (someone_came_first(obs.robots, pose[:2], goal, hc)
                     or (patient and goal_crowded(obs.robots, pose[:2], goal, hc,
                                                  self._elsewhere)))
        if self._occupant_stays(occupied, goal, obs, now):
            return HoldingDecision(HoldingKind.ABORT, reason=(
                f"goal occupied by a robot that has not moved for {hc.occupied_timeout:g} s"))
        hp.update(now, pose[:2], occupied, first)
        if hp.phase != HoldingPhase.APPROACH and fresh and not hp.held_back(now) and (
                self._swap_judged < obs.time):
            another = self._take_another(pose, costmap, obs, plan)
            if another is not None:
                return another
        if self._way_congested(hp, costmap, obs, track, holding_time, now):
            wait = hc.congestion_wait * (1.0 + 0.25 * (self.cfg.robot_index % 5))
            hp.hold_back(self._staging(costmap, pose, obs), now, wait)
        # never park on top of another robot: a taken loop point is skipped, a taken spot is
        # replaced by a staging point well away from the busy workstation
        tgt = hp.target
        if (hp.phase == HoldingPhase.TO_HOLD and fresh
                and np.hypot(*(tgt - pose[:2])) < hc.holding_target_check_range):
            if goal_occupied(obs.robots, tgt, hc):
                if hp.loop:
                    hp.advance()
                else:
                    hp.replace_target(self._staging(costmap, pose, obs))
        self._make_room(hp, costmap, pose, obs, now)
        if hp.phase == HoldingPhase.APPROACH:
            return HoldingDecision(HoldingKind.DRIVE,
                                   replan=before_phase != HoldingPhase.APPROACH)
        moved = before_target is None or not np.allclose(before_target, hp.target)
        kind = HoldingKind.WAIT if hp.phase == HoldingPhase.WAIT else HoldingKind.HOLD
        return HoldingDecision(kind, replan=moved)

    # ------------------------------------------------------------------ the rules
    def _occupant_stays(self, occupied: bool | None, goal: np.ndarray, obs: ObstacleSet,
                        now: float) -> bool:
        """Whether the goal has been seen taken for ``occupied_timeout`` by a robot that does not
        move: at every judgement in that time the goal was in sight and taken, and no robot was
        seen moving (faster than ``moving_speed``) within 2 x ``goal_occupied_radius`` of it. A
        queue at a workstation moves whenever a robot docks or leaves; a robot that died on it
        never does. The goal is then unreachable, and given up (aborted with the reason:
        docs/reference/contract.md#s5-navigation) rather than held for ever (why:
        docs/design/navigator.md#occupied-timeout).

        Args:
            occupied: this tick's judgement (None: not judged, out of sight or no fresh scan).
            goal: (2,) x, y [m] in ``map``.
            obs: the robots seen.
            now: time [s].
        """
        hc = self.cfg.holding
        near = np.hypot(*(obs.seen.centres - goal).T) <= 2.0 * hc.goal_occupied_radius
        if not occupied or bool((obs.moving() & near).any()):
            self._occupied_since = None
            return False
        if self._occupied_since is None:
            self._occupied_since = now
        return hc.occupied_timeout > 0 and now - self._occupied_since >= hc.occupied_timeout

    def _take_another(self, pose: np.ndarray, costmap: Costmap, obs: ObstacleSet,
                      plan: Callable[[np.ndarray, np.ndarray], PlanResult]
                      ) -> HoldingDecision | None:
        """While holding for a workstation, take another one of its kind instead, if one is free.

        Judged once per fresh scan, when not held back by congestion: the nearest workstation of
        the goal's kind (:attr:`kinds`), other than the goal's own and the one of the last goal
        reached (the robot would only go back where it came from), within ``swap_range`` of the
        robot and in line of sight, that no robot stands on or drives onto, that no nearer robot
        is heading for, and where no robots queue (the judgements made for the goal itself:
        :func:`~swarm_nav.holding.goal_occupied`, :func:`~swarm_nav.holding.someone_came_first`,
        :func:`~swarm_nav.holding.goal_crowded`). The goal becomes that workstation's docking pose
        (``nav_status`` reports it; the goal id stays), the holding pattern starts afresh for it.
        Our design: the contract has the robot hold until its own goal is free
        (docs/reference/contract.md#s5-navigation; why:
        docs/design/navigator.md#taking-another-workstation).

        Returns:
            The NEW_GOAL decision, or ``None`` (no such workstation, or no plan to it).
        """
        hc = self.cfg.holding
        self._swap_judged = obs.time
        if hc.swap_range <= 0 or not self.kinds:
            return None
        own = goal_site(self._goal[:2], self.sites, hc)
        if own is None:
            return None
        best, best_d = None, math.inf
        for i, (p, _h) in enumerate(self.sites):
            if i in (own, self._last_site) or self.kinds[i] != self.kinds[own]:
                continue
            d = float(np.hypot(*(p[:2] - pose[:2])))
            if d > hc.swap_range or d >= best_d:
                continue
            if (not goal_visible(costmap, pose[:2], p[:2], hc)
                    or goal_occupied(obs.robots, p[:2], hc)
                    or someone_came_first(obs.robots, pose[:2], p[:2], hc)
                    or goal_crowded(obs.robots, pose[:2], p[:2], hc, self._other_sites(p[:2]))):
                continue
            best, best_d = i, d
        if best is None:
            return None
        res = plan(pose[:2], self.sites[best][0][:2])
        if res.path is None:
            return None
        self.swaps += 1
        if self.sent_goal is None:
            self.sent_goal = self._goal.copy()
        self._occupied_since = None
        return HoldingDecision(HoldingKind.NEW_GOAL, goal=self.sites[best][0][:3].copy(),
                               plan=res)

    def _way_congested(self, hp: HoldingPattern, costmap: Costmap, obs: ObstacleSet,
                       track: PathTracker, holding_time: float, now: float) -> bool:
        """Whether the way to the goal (or to its holding spot) is congested
        (:func:`~swarm_nav.holding.path_congested`), judged once per scan while driving there.

        A starving robot (``starvation_time`` > 0: one that has reached no goal since the
        navigator started and has held ``starvation_time`` for this goal), and an impatient one
        (``patience_time`` > 0: one that has held that long for this goal), is held back only
        by a longer queue, ``starvation_congestion_limit`` robots (0: by none). Why, and why with
        these defaults: docs/design/navigator.md#congestion and #starvation.
        """
        hc = self.cfg.holding
        limit = hc.congestion_limit
        if ((hc.starvation_time > 0 and not self.reached_goal
             and holding_time >= hc.starvation_time)
                or (hc.patience_time > 0 and holding_time >= hc.patience_time)):
            limit = hc.starvation_congestion_limit
        if (hc.congestion_limit <= 0 or limit <= 0 or track.path is None or hp.rerouted
                or hp.phase == HoldingPhase.WAIT or obs.time <= self._congestion_judged
                or not obs.fresh(now)):
            return False
        self._congestion_judged = obs.time
        seen = obs.seen
        if len(seen.centres) < limit:
            return False
        return path_congested(seen.centres, ~obs.moving(), track.ahead(hc.congestion_distance),
                              track.path[-1], self.avoid, costmap.distance_at(seen.centres), hc,
                              limit)

    def _make_room(self, hp: HoldingPattern, costmap: Costmap, pose: np.ndarray,
                   obs: ObstacleSet, now: float) -> None:
        """A waiting robot that another robot stays close to (``make_room_distance``, for
        ``make_room_time``) moves away to a staging point."""
        hc = self.cfg.holding
        centres = obs.seen.centres
        close = len(centres) and bool(
            np.hypot(*(centres - pose[:2]).T).min() < hc.make_room_distance)
        if hp.phase != HoldingPhase.WAIT or not close:
            self._crowded_since = None
            return
        if self._crowded_since is None:
            self._crowded_since = now
        elif now - self._crowded_since >= hc.make_room_time:
            self._crowded_since = None
            hp.relocate(self._staging(costmap, pose, obs), now)

    def _staging(self, costmap: Costmap, pose: np.ndarray, obs: ObstacleSet) -> np.ndarray:
        """A staging point away from the goal and the robots seen (or where the robot is)."""
        xy = staging_point(costmap, self._goal[:2], pose[:2], obs.seen.centres, self.avoid,
                           self.cfg.holding)
        return pose[:2].copy() if xy is None else xy

    def _other_sites(self, goal_xy: np.ndarray) -> np.ndarray:
        """(J, 2) x, y [m] of the workstations and holding points that are not the goal's own
        (its workstation: :func:`~swarm_nav.holding.goal_site`)."""
        own = goal_site(goal_xy, self.sites, self.cfg.holding)
        pts = [np.vstack((p[None, :2], h)) for i, (p, h) in enumerate(self.sites) if i != own]
        return np.vstack(pts) if pts else np.zeros((0, 2))
