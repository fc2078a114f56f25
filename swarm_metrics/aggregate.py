"""Run figures from the navigators' status stream, the swarm events and the simulator's summary.

Pure: no ROS import.  :class:`RunRecorder` is fed plain dicts (the metrics node converts
``diagnostic_msgs`` messages into them) and :func:`aggregate` turns its state, the simulator's
``--summary`` JSON and the orchestrator's own figures into the ``--metrics`` dict
(docs/reference/contract.md#s6).

Definitions (``docs/ARCHITECTURE.md``, ``/<ns>/nav_status``):

- *ready*: the first status a robot's navigator publishes; ``spawn_to_ready_s`` is the wall time
  from the start of the run (the simulator's launch) to the moment the last robot became ready.
- *goal reached* / *aborted*: a goal id whose state became ``SUCCEEDED`` / ``ABORTED``; each goal
  id counts once, however often the status is re-published (and a restarted navigator's
  re-publication of the same goal is not counted twice).  A status without a goal id counts on the
  transition into the state.
- *time to goal*: ``navigation_time_s`` of the first ``SUCCEEDED`` status of a goal [s].
- *holding time*: the latest ``holding_time_s`` of every goal, summed [s].
- *late ticks*: ticks an active robot did not answer because its navigator was gone (a crash
  the supervisor reported, or no ``cmd_vel`` writer left: :mod:`swarm_common.supervision`); the
  robot stands still until its successor answers. The lockstep has no wall-clock timeout, so a
  slow or paused process makes no late tick.
- *goal-wait timeouts*: ticks a navigator answered without its commander's next goal because
  the wait (``goal_wait_timeout``) ran out, summed over restarts; only a commander outside the
  lockstep (not started by ``swarm-up``) can cause one; see *reproducible*.
- *reproducible*: the run's simulated figures depend on the seed alone, as far as the run can
  tell: no late tick, no goal-wait timeout, no late goal and no restart but those the fault
  schedule caused (each lets wall-clock timing decide something the simulation then depends
  on); None when the late ticks are unknown.
- *task*: one goal reached (every commander goal is one workstation visit), so
  ``tasks_completed == goals_reached`` and ``throughput_per_hour`` is tasks per simulated hour;
  ``task_times_s`` lists the simulated time of every task's first ``SUCCEEDED`` status, sorted
  (tasks over time, e.g. around a fault), and ``task_durations_s`` each one's time to task, in
  the same order (their distribution).
- *faults*: injected faults (:mod:`swarm_common.faults`) that started: ``faults`` in all,
  ``faults_by_kind``, and ``fault_log`` (every start and end: id, kind, phase, robot, simulated
  time [s] and the robot's x, y [m] in ``map``), from the simulator's summary (its log of what
  it applied), else from the ``/swarm/events`` announcements seen; ``fault_messages_dropped`` by
  ``drop`` faults. The simulator's own "stopped answering" events (a navigator that went silent)
  are ``unresponsive_events``. A restart caused by a fault does not make a run irreproducible
  (the schedule decides it, and the simulator holds the fault's tick until it is carried out).
- *task*: one workstation visit. Decentralized: one goal reached (every commander goal is a
  workstation), so ``tasks_completed == goals_reached``. Centralized: one ``task`` event of the
  coordinator (a robot reported it reached its reserved workstation); goals to waiting spots are
  goals, not tasks. ``throughput_per_hour`` is tasks per simulated hour;
  ``throughput_after_warmup_per_hour`` counts only tasks completed after the first
  ``warmup_s`` (120 s) of simulated time, over the time after it (None for shorter runs).
- *time to task* (``time_to_task_*``): decentralized, the goal's navigation time; centralized,
  from the robot's request for the task to its arrival at the workstation, waiting at a spot
  included (the coordinator's ``duration_s``): the time the robot needed for the task either way.
- *waiting at spots* (``coordinator_wait_s``, centralized): simulated seconds robots held a
  waiting spot (reserve to release, or to the end of the run).
- *tasks per window* (``tasks_per_window``): tasks completed in each ``task_window_s`` (600 s)
  of simulated time, from t = 0; the last window is cut short by the end of the run when the
  run is not a whole number of windows (``task_windows_full`` says how many are whole).
  ``task_window_ratio_min`` is the fewest tasks of a whole window after the first, over the mean
  of those windows (issue 9's steadiness check: >= 0.85 means no jam built up; None with fewer
  than one whole window after the first).
- *tasks per robot* (``tasks_per_robot``): the spread of the tasks over the robots: ``min``,
  ``median`` and ``max`` of each robot's tasks, and ``without_task``, how many robots completed
  none (issue 9: every robot must complete tasks; a swarm can be steady while some of its
  robots starve). None with no robot.
- *workstations* (``workstations``): one row per workstation of the world's points of interest,
  in file order, for the goals whose pose (``goal_x``, ``goal_y`` of ``nav_status``) lies within
  ``WORKSTATION_MATCH_M`` (0.5 m) of its docking pose: ``goals`` sent there, ``visits`` (goals
  reached), ``aborted``, ``mean_time_to_goal_s``, ``holding_time_s`` (summed over its goals) and
  ``mean_wait_s`` (holding time per goal: how long a robot sent there waited in its holding
  pattern). Goals near no workstation (a centralized run's waiting spots) are the row
  ``(other)``, listed only when there are any.
- *spawn* (``spawn``): where the simulator put the robots, its ``spawned N robots in ...`` line's
  text (:func:`swarm_scene.spawn.describe_spawn`): the rule (the spawn area of the world's points
  of interest, else the largest enclosed free region or the largest free region, its area, and
  why), the block x, y [m] in ``map`` they stand in
  and the first robot's place; None without the simulator's summary.
- *world elements skipped* (``world_skipped``): the world's skip report
  (:attr:`swarm_scene.world.World.skipped`, one text per element the simulator leaves out, e.g.
  ``"actor 'walker'"``), from the simulator's summary; ``[]`` when the world loads whole, None
  without the summary.
- *standstills* (``standstills``): the simulator's episodes of a robot standing within 0.1 m
  for 60 simulated s or more (:mod:`swarm_sim.standstill`), each with ``near``: the workstation
  whose docking pose or holding points are nearest (within ``STANDSTILL_NEAR_M``, 3 m), else
  None; ``standstill_s`` sums their durations.
- *late goals*: goals a navigator applied later than the first control tick after the goal's
  stamp (the tick it was applied at is the first status's ``stamp`` minus its
  ``navigation_time_s``): the goal arrived after that tick, so wall-clock timing decided when
  it took effect. Zero in a reproducible run; counted in *reproducible*.
- *reservation conflicts*: the :func:`swarm_common.coordination.check_reservations` violations
  in the coordinator's events (a resource reserved while another robot held it); must be 0.
- *coordinator lapses*: the coordinator's ``lapse`` events (centralized; how it noticed a robot
  that died or fell silent): robot, simulated time [s], the workstation it lost, and why
  (``lease``, ``silence``, ``dead``: :data:`swarm_common.coordination.LAPSE_REASONS`).
- *communication load* (``comm``): the messages, and their serialized (CDR) bytes, that cross
  between a robot and a central node: the coordinator's three topics (every request, every
  assignment, one ``state`` copy per robot per coordinator start) and the map distribution
  (one latched ``/map`` per navigator start). Not counted: the simulator's topics (``/clock``,
  ``odom``, ``scan``, ``cmd_vel``, ``ground_truth``: they stand for each robot's own sensors and
  motors), a robot's own ``goal_pose``/``nav_status``/``navigator/cancel`` (navigator and
  commander run on the same robot) and ``/swarm/events`` (instrumentation). DDS/RTPS headers,
  discovery and acknowledgements are not counted, nor re-sends (a byte-identical copy of a
  request or an answer, whose number depends on wall-clock timing: ``comm.resent``). Per
  simulated second: divided by ``sim_time_s``.
"""

from __future__ import annotations

import math
import statistics
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from swarm_common.coordination import (
    EVENT_COORDINATOR,
    EVENT_LAPSE,
    EVENT_RESERVATION,
    EVENT_TASK,
    check_reservations,
)
from swarm_common.events import COLLISION, LATE, ROBOT_ROBOT, ROBOT_WALL, SPAWN, CollisionEvent
from swarm_common.faults import EVENT_NAME as FAULT
from swarm_common.faults import FaultEvent
from swarm_common.nav_status import TOOK_ANOTHER, NavState, decode, finite_float
from swarm_common.sim_summary import RobotSummary, SimSummary, SimSummaryError
from swarm_common.stamps import NS_PER_S, parse_stamp

WARMUP_S = 120.0  # [s] simulated: the protocol's warm-up, left out of the warm-up throughput
TASK_WINDOW_S = 600.0  # [s] simulated: issue 9's 10-minute windows of tasks completed
WORKSTATION_MATCH_M = 0.5  # [m] a goal this near a workstation's docking pose is a goal to it
OTHER_GOALS = "(other)"  # the workstation table's row of goals near no workstation
STANDSTILL_NEAR_M = 3.0  # [m] a standstill this near a workstation's points is "near" it
COMM_TOPICS = ("map", "request", "assignment", "state")

SIM_SUMMARY_KEYS = (
    "ticks",
    "sim_time_s",
    "wall_time_s",
    "late_ticks",
    "collisions",
    "min_separation_m",
    "per_robot",
)


@dataclass
class RobotRecord:
    """What the recorder knows about one robot."""

    ready_wall_s: float | None = None  # [s] since the run's start
    state: NavState | None = None  # as last published (None: none yet, or unknown)
    statuses: int = 0
    reached: dict[str, float | None] = field(default_factory=dict)  # goal id -> time to goal [s]
    aborted: set[str] = field(default_factory=set)
    abort_reasons: dict[str, str] = field(default_factory=dict)
    holding_s: dict[str, float] = field(default_factory=dict)  # goal id -> latest holding [s]
    anonymous_reached: int = 0
    anonymous_aborted: int = 0
    took_another: int = 0  # goals reached at another workstation than the one sent
    anonymous_ttg: list[float] = field(default_factory=list)
    collisions: int = 0  # from /swarm/events
    spawned: bool = False
    late_events: int = 0
    goal_wait_timeouts: int = 0  # the navigator's counter, as last published
    goal_wait_timeouts_before: int = 0  # the counters of earlier (restarted) navigator processes
    task_times: list[float] = field(default_factory=list)  # simulated [s]: each first SUCCEEDED
    reached_at: dict[str, float] = field(default_factory=dict)  # goal id -> simulated [s] reached
    goal_xy: dict[str, tuple[float, float]] = field(default_factory=dict)  # goal id -> x, y [m]
    applied: set[str] = field(default_factory=set)  # goal ids seen applied
    late_goals: int = 0  # goals applied after the first tick after their stamp
    late_goal_ids: list[str] = field(default_factory=list)  # "<goal id> applied at <t>" (first 10)
    tasks: list[tuple[float, float, str]] = field(default_factory=list)  # (t, duration [s], ws)
    comm_messages: int = 0  # messages to/from central nodes (coordinator, /map)
    comm_bytes: int = 0

    @property
    def goal_wait_timeouts_total(self) -> int:
        """Goal-wait timeouts of every process this robot's navigator ran in."""
        return self.goal_wait_timeouts_before + self.goal_wait_timeouts


@dataclass
class RunRecorder:
    """Incremental state of a run, fed by the metrics node.

    Args:
        robots: the namespaces, without the leading ``/`` (``Srobot1`` ...).
    """

    robots: tuple[str, ...]
    per_robot: dict[str, RobotRecord] = field(default_factory=dict)
    last_sim_time_s: float | None = None  # [s] latest /clock
    collision_events: dict[str, int] = field(default_factory=lambda: {ROBOT_ROBOT: 0,
                                                                      ROBOT_WALL: 0})
    fault_events: int = 0  # the simulator's "stopped answering" / "answers again" events
    # every collision event in order: robot, other, kind, x, y [m], t [s] simulated
    collision_log: list[dict] = field(default_factory=list)
    fault_log: list[FaultEvent] = field(default_factory=list)  # injected faults, in order
    spawn_events: int = 0
    period_s: float = 0.1  # [s] the control tick (late goals)
    reservation_events: list[dict[str, str]] = field(default_factory=list)
    lapse_events: list[dict[str, str]] = field(default_factory=list)  # the coordinator's lapses
    coordinator_epochs: set[str] = field(default_factory=set)  # one per coordinator start
    # epochs whose "up" event came: that coordinator has synced and answers requests
    coordinator_serving: set[str] = field(default_factory=set)
    comm_by_topic: dict[str, list[int]] = field(default_factory=dict)  # topic -> [msgs, bytes]
    map_bytes: int | None = None  # serialized size of the latest /map
    comm_resent: int = 0  # byte-identical copies of requests and assignments (re-sends)
    _comm_seen: set = field(default_factory=set, repr=False)

    def __post_init__(self) -> None:
        for ns in self.robots:
            self.per_robot.setdefault(ns, RobotRecord())

    # ---------------------------------------------------------------- inputs
    def on_status(self, robot: str, values: dict[str, str], wall_s: float,
                  message: str = "") -> None:
        """One ``/<ns>/nav_status`` message.

        Args:
            robot: namespace without ``/``.
            values: the status's ``values`` as a dict of strings
                (:func:`swarm_common.nav_status.decode` reads them).
            wall_s: receive time since the run's start [s].
            message: the status's ``message`` (the state, used if ``values`` has none).
        """
        rec = self.per_robot.setdefault(robot, RobotRecord())
        rec.statuses += 1
        if rec.ready_wall_s is None:
            rec.ready_wall_s = wall_s
        status = decode(values, message)  # malformed values come back as None
        goal, state = status.goal_id, status.state
        previous, rec.state = rec.state, state
        waits = status.goal_wait_timeouts
        if waits is not None:
            if waits < rec.goal_wait_timeouts:  # a restarted navigator counts from 0 again
                rec.goal_wait_timeouts_before += rec.goal_wait_timeouts
            rec.goal_wait_timeouts = waits
        if goal and status.holding_time is not None:
            rec.holding_s[goal] = status.holding_time
        if goal and status.goal is not None:  # the latest: a holding robot may take another
            rec.goal_xy[goal] = (status.goal[0], status.goal[1])  # workstation (swap_range)
        if goal and goal not in rec.applied and status.stamp_ns is not None \
                and status.navigation_time is not None and state not in (None, NavState.IDLE):
            rec.applied.add(goal)
            goal_ns = parse_stamp(goal)
            if goal_ns is not None:  # (a rejected goal's status is stamped before: not late)
                period_ns = round(self.period_s * NS_PER_S)
                expected = (goal_ns // period_ns + 1) * period_ns
                applied = status.stamp_ns - round(status.navigation_time * NS_PER_S)
                if applied - expected > NS_PER_S // 500:  # beyond the 3 decimals' rounding
                    rec.late_goals += 1
                    if len(rec.late_goal_ids) < 10:
                        rec.late_goal_ids.append(f"{goal} applied at {applied / NS_PER_S:.3f} "
                                                 f"({state.value}, {status.stamp_ns}, "
                                                 f"{status.navigation_time})")
        if state == NavState.SUCCEEDED and goal and goal not in rec.reached_at \
                and status.stamp_ns is not None:
            rec.reached_at[goal] = status.stamp_ns / NS_PER_S
        if state == NavState.SUCCEEDED:
            ttg = status.navigation_time
            if goal:
                if goal not in rec.reached:
                    rec.reached[goal] = ttg
                    rec.took_another += status.reason.startswith(TOOK_ANOTHER)
                    if status.stamp_ns is not None:
                        rec.task_times.append(status.stamp_ns / 1e9)
            elif previous != NavState.SUCCEEDED:
                rec.anonymous_reached += 1
                if ttg is not None:
                    rec.anonymous_ttg.append(ttg)
        elif state == NavState.ABORTED:
            if goal:
                if goal not in rec.aborted:
                    rec.aborted.add(goal)
                    rec.abort_reasons[goal] = status.reason
            elif previous != NavState.ABORTED:
                rec.anonymous_aborted += 1

    def on_event(self, kind: str, values: dict[str, str]) -> None:
        """One event (one ``DiagnosticStatus``) of ``/swarm/events``.

        Args:
            kind: the status ``name`` (:data:`swarm_common.events.KINDS`).
            values: its values (the fields of the kind's record, :mod:`swarm_common.events`).
        """
        robot = values.get("robot", "").strip().lstrip("/")
        rec = self.per_robot.get(robot)
        if kind == COLLISION:
            ev = CollisionEvent.decode(values, lenient=True)  # counted where it is unknown
            if ev is None:
                return  # no robot: not counted
            self.collision_log.append({"robot": ev.robot, "other": ev.other, "kind": ev.kind,
                                       "x": ev.x, "y": ev.y, "t": ev.t})
            if ev.other in self.per_robot:
                self.collision_events[ROBOT_ROBOT] += 1
                self.per_robot[ev.other].collisions += 1
            else:
                self.collision_events[ROBOT_WALL] += 1
            if rec is not None:
                rec.collisions += 1
        elif kind == SPAWN:
            self.spawn_events += 1
            if rec is not None:
                rec.spawned = True
        elif kind == LATE:
            if rec is not None:
                rec.late_events += 1
        elif kind == FAULT:
            injected = FaultEvent.decode(values)
            if injected is None:
                self.fault_events += 1
            else:
                self.fault_log.append(injected)
        elif kind == EVENT_RESERVATION:
            self.reservation_events.append(dict(values))
        elif kind == EVENT_LAPSE:
            self.lapse_events.append(dict(values))
        elif kind == EVENT_TASK:
            t, start = parse_stamp(values.get("t", "")), parse_stamp(values.get("t_start", ""))
            if rec is not None and t is not None and start is not None:
                rec.tasks.append((t / NS_PER_S, (t - start) / NS_PER_S,
                                  values.get("workstation", "")))
        elif kind == EVENT_COORDINATOR:
            epoch = values.get("epoch", "")
            self.on_coordinator_up(epoch)
            self.coordinator_serving.add(epoch)

    def on_coordinator_up(self, epoch: str) -> None:
        """A coordinator started with this epoch: heard as its "up" event on ``/swarm/events``
        or as its latched ``state`` message (transient local, so a late reader still gets it);
        each epoch counts once."""
        self.coordinator_epochs.add(epoch)

    @property
    def coordinator_starts(self) -> int:
        """How many coordinators started (distinct epochs heard)."""
        return len(self.coordinator_epochs)

    def on_comm(self, topic: str, robot: str, nbytes: int, key: str | None = None) -> None:
        """One message between a robot and a central node (see *communication load*).

        Args:
            topic: one of :data:`COMM_TOPICS`.
            robot: the robot it went to or came from; "" for a message every robot receives
                (one copy per robot is counted).
            nbytes: its serialized size [bytes].
            key: the message's text, if a byte-identical copy is a re-send (a request sent
                again because no answer came in time, and the repeated answer): re-sends are
                counted apart (``comm.resent``), as their number depends on wall-clock timing.
        """
        if key is not None:
            if (topic, key) in self._comm_seen:
                self.comm_resent += 1
                return
            self._comm_seen.add((topic, key))
        entry = self.comm_by_topic.setdefault(topic, [0, 0])
        for ns in [robot] if robot else list(self.robots):
            rec = self.per_robot.get(ns)
            if rec is None:
                continue
            rec.comm_messages += 1
            rec.comm_bytes += nbytes
            entry[0] += 1
            entry[1] += nbytes

    def on_clock(self, sim_time_s: float) -> None:
        """One ``/clock`` message [s]."""
        self.last_sim_time_s = sim_time_s

    def goal_totals(self) -> tuple[int, int]:
        """``(reached, aborted)`` goals so far, all robots."""
        reached = sum(len(r.reached) + r.anonymous_reached for r in self.per_robot.values())
        aborted = sum(len(r.aborted) + r.anonymous_aborted for r in self.per_robot.values())
        return reached, aborted

    # ---------------------------------------------------------------- queries
    @property
    def ready_count(self) -> int:
        """Robots whose navigator has published at least one status."""
        return sum(1 for ns in self.robots if self.per_robot[ns].ready_wall_s is not None)

    @property
    def spawned_count(self) -> int:
        """Robots with a ``spawn`` event."""
        return sum(1 for ns in self.robots if self.per_robot[ns].spawned)

    def not_ready(self) -> list[str]:
        """Namespaces whose navigator has not published yet."""
        return [ns for ns in self.robots if self.per_robot[ns].ready_wall_s is None]

    def spawn_to_ready_s(self) -> float | None:
        """Wall time from the run's start until every robot was ready [s]; None if not all were."""
        times = [self.per_robot[ns].ready_wall_s for ns in self.robots]
        if not times or any(t is None for t in times):
            return None
        return max(times)


def load_sim_summary(path: Path | str | None) -> tuple[SimSummary, list[str]]:
    """Read the simulator's ``--summary`` file tolerantly.

    Args:
        path: the file (None: there is none).

    Returns:
        ``(summary, warnings)``: the summary (all figures None when the file is missing or
        malformed), and one warning line per problem, including the figures of
        :data:`SIM_SUMMARY_KEYS` it lacks.
    """
    if path is None:
        return SimSummary(), ["no simulator summary; simulator figures are null"]
    path = Path(path)
    try:
        summary = SimSummary.read(path)
    except FileNotFoundError:
        return SimSummary(), [f"{path}: simulator summary missing; simulator figures are null"]
    except OSError as exc:
        return SimSummary(), [f"{path}: unreadable simulator summary ({exc}); figures are null"]
    except SimSummaryError as exc:
        return SimSummary(), [f"malformed simulator summary: {exc}; figures are null"]
    missing = [k for k in SIM_SUMMARY_KEYS if getattr(summary, k) is None]
    if missing:
        return summary, [f"{path}: simulator summary lacks {', '.join(missing)}; those are null"]
    return summary, []


def _ratio(num, den) -> float | None:
    num, den = finite_float(num), finite_float(den)
    if num is None or den is None or den <= 0:
        return None
    return num / den


def _robot_metrics(rec: RobotRecord, sim: RobotSummary) -> dict:
    """One robot's ``per_robot`` entry of ``--metrics``: the recorder's goal figures, the
    simulator's distance and late ticks, its collisions (the events' count without them)."""
    return {
        "goals_reached": len(rec.reached) + rec.anonymous_reached,
        "goals_aborted": len(rec.aborted) + rec.anonymous_aborted,
        "goals_at_another_workstation": rec.took_another,
        "collisions": sim.collisions if sim.collisions is not None else rec.collisions,
        "distance_m": sim.distance_m,
        "holding_time_s": sum(rec.holding_s.values()),
        "late_ticks": sim.late_ticks,
        "goal_wait_timeouts": rec.goal_wait_timeouts_total,
        "late_goals": rec.late_goals,
        "late_goal_ids": list(rec.late_goal_ids),
        "ready_s": rec.ready_wall_s,
        "task_times_s": sorted(rec.task_times),
    }


def task_records(recorder: RunRecorder, centralized: bool) -> list[tuple[float, float, str]]:
    """Every task with a known time: ``(completed at [s] sim, time to task [s], robot)``,
    sorted by completion time (see *task* and *time to task* in the module doc)."""
    out = []
    for ns in recorder.robots:
        rec = recorder.per_robot[ns]
        if centralized:
            out += [(t, d, ns) for t, d, _ in rec.tasks]
        else:
            out += [(rec.reached_at[g], d, ns) for g, d in rec.reached.items()
                    if g in rec.reached_at and d is not None]
    return sorted(out)


def tasks_per_window(times_s: list[float], sim_time_s: float | None,
                     window_s: float = TASK_WINDOW_S) -> dict:
    """Tasks completed per window of simulated time (see *tasks per window*).

    Args:
        times_s: completion times of the tasks [s] simulated.
        sim_time_s: the run's simulated length [s] (None: up to the last task).
        window_s: window length [s] (> 0).

    Returns:
        ``tasks_per_window`` (list of counts, window k covering ``[k w, (k + 1) w)``; a task at
        exactly ``sim_time_s`` counts in the last window), ``task_window_s``,
        ``task_windows_full`` (whole windows) and ``task_window_ratio_min``.
    """
    end = sim_time_s if sim_time_s is not None else max(times_s, default=0.0)
    n_windows = max(1, math.ceil(end / window_s - 1e-9)) if end > 0 else 0
    counts = [0] * n_windows
    for t in times_s:
        if n_windows:
            counts[min(n_windows - 1, max(0, int(t // window_s)))] += 1
    full = int(end // window_s + 1e-9) if end > 0 else 0
    later = counts[1:full]
    mean = sum(later) / len(later) if later else 0.0
    return {
        "tasks_per_window": counts,
        "task_window_s": window_s,
        "task_windows_full": full,
        "task_window_ratio_min": (min(later) / mean) if later and mean > 0 else None,
    }


def tasks_per_robot(counts: list[int]) -> dict | None:
    """The spread of the tasks over the robots (see *tasks per robot*).

    Args:
        counts: each robot's tasks completed.

    Returns:
        ``{"min", "median", "max", "without_task"}`` (the median of an even count is the mean of
        the middle two), or None when ``counts`` is empty.
    """
    if not counts:
        return None
    return {"min": min(counts), "median": statistics.median(counts), "max": max(counts),
            "without_task": sum(1 for c in counts if c == 0)}


def workstation_table(recorder: RunRecorder, workstations: Mapping[str, tuple[float, float]],
                      match_m: float = WORKSTATION_MATCH_M) -> list[dict]:
    """Goals, visits and waiting per workstation (see *workstations*).

    Args:
        recorder: the run's recorder.
        workstations: name -> docking x, y [m] in ``map``, in the table's order.
        match_m: a goal within this distance [m] of a docking pose is a goal to it (the
            nearest one when several are).

    Returns:
        One dict per workstation (name, x, y, goals, visits, aborted, mean_time_to_goal_s,
        holding_time_s, mean_wait_s), then ``(other)`` when some goals matched none.
    """
    names = list(workstations)
    xy = [tuple(map(float, workstations[n][:2])) for n in names]
    rows = {n: {"goals": 0, "visits": 0, "aborted": 0, "ttg": [], "holding": 0.0}
            for n in [*names, OTHER_GOALS]}
    for rec in recorder.per_robot.values():
        for goal, (gx, gy) in rec.goal_xy.items():
            dists = [math.hypot(gx - x, gy - y) for x, y in xy]
            near = min(range(len(dists)), key=dists.__getitem__) if dists else None
            row = rows[names[near] if near is not None and dists[near] <= match_m
                       else OTHER_GOALS]
            row["goals"] += 1
            if goal in rec.reached:
                row["visits"] += 1
                if rec.reached[goal] is not None:
                    row["ttg"].append(rec.reached[goal])
            if goal in rec.aborted:
                row["aborted"] += 1
            row["holding"] += rec.holding_s.get(goal, 0.0)
    out = []
    for i, name in enumerate([*names, OTHER_GOALS]):
        row = rows[name]
        if name == OTHER_GOALS and row["goals"] == 0:
            continue
        out.append({
            "name": name,
            "x": xy[i][0] if i < len(xy) else None,
            "y": xy[i][1] if i < len(xy) else None,
            "goals": row["goals"],
            "visits": row["visits"],
            "aborted": row["aborted"],
            "mean_time_to_goal_s": (sum(row["ttg"]) / len(row["ttg"])) if row["ttg"] else None,
            "holding_time_s": row["holding"],
            "mean_wait_s": (row["holding"] / row["goals"]) if row["goals"] else None,
        })
    return out


def label_standstills(episodes, places: Mapping[str, list[tuple[float, float]]],
                      near_m: float = STANDSTILL_NEAR_M) -> list[dict]:
    """The simulator's standstill episodes, each with the workstation it stood nearest.

    Args:
        episodes: the summary's ``standstills`` (dicts with ``x``, ``y`` [m] in ``map``); entries
            that are not dicts with finite ``x``, ``y`` are dropped.
        places: workstation name -> its docking and holding points, x, y [m] in ``map``.
        near_m: the farthest [m] a standstill may be from a workstation's points to be near it.

    Returns:
        The episodes as dicts with ``near`` (a workstation name or None) added.
    """
    out = []
    for ep in episodes if isinstance(episodes, list) else []:
        if not isinstance(ep, Mapping):
            continue
        x, y = finite_float(ep.get("x")), finite_float(ep.get("y"))
        if x is None or y is None:
            continue
        best, best_d = None, near_m
        for name, points in places.items():
            d = min((math.hypot(x - px, y - py) for px, py in points), default=math.inf)
            if d <= best_d:
                best, best_d = name, d
        out.append({**ep, "near": best})
    return out


def _spot_wait_s(events: list[dict[str, str]], end_s: float | None) -> float:
    """Simulated seconds robots held waiting spots (reserve to release, or to ``end_s``)."""
    since: dict[tuple[str, str], float] = {}
    total = 0.0
    for ev in events:
        res = ev.get("resource", "")
        t = parse_stamp(ev.get("t", ""))
        if not res.startswith("spot:") or t is None:
            continue
        key = (res, ev.get("robot", ""))
        if ev.get("action") == "reserve":
            since.setdefault(key, t / NS_PER_S)
        elif key in since:
            total += t / NS_PER_S - since.pop(key)
    if end_s is not None:
        total += sum(max(0.0, end_s - t0) for t0 in since.values())
    return total


def _percentile(values: list[float], q: float) -> float | None:
    if not values:
        return None
    import numpy as np

    return float(np.percentile(np.asarray(values, float), q))


def _comm(recorder: RunRecorder, map_deliveries: dict[str, int] | None,
          sim_time: float | None) -> dict:
    """The ``comm`` entry (see *communication load*)."""
    by_topic = {k: list(v) for k, v in recorder.comm_by_topic.items()}
    per_robot = {ns: [recorder.per_robot[ns].comm_messages, recorder.per_robot[ns].comm_bytes]
                 for ns in recorder.robots}
    if recorder.map_bytes is not None:
        deliveries = map_deliveries or {ns: 1 for ns in recorder.robots}
        entry = by_topic.setdefault("map", [0, 0])
        for ns, copies in deliveries.items():
            if ns in per_robot:
                per_robot[ns][0] += copies
                per_robot[ns][1] += copies * recorder.map_bytes
                entry[0] += copies
                entry[1] += copies * recorder.map_bytes
    messages = sum(m for m, _ in per_robot.values())
    nbytes = sum(b for _, b in per_robot.values())

    def rate(x):
        return x / sim_time if sim_time else None

    return {
        "messages": messages, "bytes": nbytes,
        "messages_per_s": rate(messages), "bytes_per_s": rate(nbytes),
        "by_topic": {k: {"messages": m, "bytes": b, "messages_per_s": rate(m),
                         "bytes_per_s": rate(b)} for k, (m, b) in sorted(by_topic.items())},
        "per_robot": {ns: {"messages": m, "bytes": b, "messages_per_s": rate(m),
                           "bytes_per_s": rate(b)} for ns, (m, b) in per_robot.items()},
        "map_bytes": recorder.map_bytes,
        "resent": recorder.comm_resent,
    }


def _times_to_goal(rec: RobotRecord) -> list[float]:
    """A robot's known times to goal [s]: goals with an id, then those without."""
    return [t for t in rec.reached.values() if t is not None] + rec.anonymous_ttg


def _collisions(recorder: RunRecorder, sim: SimSummary) -> dict:
    """The run's collisions by kind: the simulator's, else the ``/swarm/events`` count."""
    if sim.collisions is None:
        return dict(recorder.collision_events)
    return {"robot_robot": sim.collisions.robot_robot, "robot_wall": sim.collisions.robot_wall}


def _late_ticks(recorder: RunRecorder, sim: SimSummary) -> int | None:
    """The simulator's late ticks, else the ``late`` events seen (None if there were none)."""
    if sim.late_ticks is not None:
        return sim.late_ticks
    late = sum(r.late_events for r in recorder.per_robot.values())
    return late if late else None


@dataclass(frozen=True)
class RunFacts:
    """What the orchestrator knows of a run besides its recorder and the simulator's summary.

    Attributes:
        world: the world's name.
        seed: the run's seed.
        coordination: ``decentralized`` | ``centralized``.
        wall_time_s: the orchestrator's wall time from start to stop [s] (used when the
            simulator's own ``wall_time_s`` is missing).
        resources: ``cpu_percent`` [%] and ``peak_rss_mb_per_robot`` [MB] (ResourceSampler).
        restarts: restarts of navigators/commanders/groups.
        extra: more keys to add (run directory, process layout, ...).
        fault_restarts: those of ``restarts`` that injected faults caused.
        map_deliveries: ``/map`` copies each robot's navigator received (one per process
            start); None: one each.
        workstations: name -> docking x, y [m] in ``map`` of the world's workstations, in
            file order (None or empty: ``workstations`` lists only ``(other)``).
        holding: name -> the holding points x, y [m] in ``map`` of each workstation (to say
            which workstation a standstill was near).
        models: the robot model of every robot (name or path), in the recorder's robot order:
            ``fleet`` (model -> robots, :func:`swarm_scene.fleet.fleet_counts`) and each
            ``per_robot`` entry's ``robot``; None: neither.
        map_path: the run's map YAML (the waiting measure's free space); None: no waiting
            measure.
    """

    world: str
    seed: int
    coordination: str
    wall_time_s: float
    resources: dict | None = None
    restarts: int = 0
    extra: dict | None = None
    fault_restarts: int = 0
    map_deliveries: dict[str, int] | None = None
    workstations: Mapping[str, tuple[float, float]] | None = None
    holding: Mapping[str, list[tuple[float, float]]] | None = None
    models: Sequence[str] | None = None
    map_path: str | None = None

    @property
    def centralized(self) -> bool:
        """Whether a central coordinator assigned the tasks."""
        return self.coordination == "centralized"


@dataclass(frozen=True)
class Timing:
    """The run's time: the simulator's figures, else the recorder's ``/clock`` and the
    orchestrator's wall time.

    Attributes:
        robots: N [-].
        sim_time_s: [s] simulated, or None.
        wall_time_s: [s] wall of the simulation loop (the orchestrator's if unknown).
        ticks: control ticks stepped, or None.
    """

    robots: int
    sim_time_s: float | None
    wall_time_s: float
    ticks: int | None

    @classmethod
    def of(cls, recorder: RunRecorder, sim: SimSummary, wall_time_s: float) -> Timing:
        sim_time = finite_float(sim.sim_time_s)
        if sim_time is None:
            sim_time = recorder.last_sim_time_s
        sim_wall = finite_float(sim.wall_time_s)
        return cls(len(recorder.robots), sim_time,
                   sim_wall if sim_wall is not None else wall_time_s, sim.ticks)

    def fields(self, orchestrator_wall_s: float) -> dict:
        """``sim_time_s`` .. ``robot_ticks_per_s`` of ``metrics.json``."""
        return {
            "sim_time_s": self.sim_time_s,
            "wall_time_s": self.wall_time_s,
            "orchestrator_wall_time_s": orchestrator_wall_s,
            "rtf": _ratio(self.sim_time_s, self.wall_time_s),
            "ticks": self.ticks,
            "robot_ticks_per_s": (_ratio(self.ticks * self.robots, self.wall_time_s)
                                  if self.ticks is not None else None),
        }


@dataclass(frozen=True)
class TaskFigures:
    """The run's tasks (see *task* above) and what follows from them.

    Attributes:
        tasks: ``(t [s], duration [s], workstation)`` of every task, in time order.
        completed: tasks completed [-].
        sim_time_s: [s] simulated, or None.
    """

    tasks: list[tuple[float, float, str]]
    completed: int
    sim_time_s: float | None

    @classmethod
    def of(cls, recorder: RunRecorder, centralized: bool, goals_reached: int,
           sim_time_s: float | None) -> TaskFigures:
        completed = (sum(len(recorder.per_robot[ns].tasks) for ns in recorder.robots)
                     if centralized else goals_reached)
        return cls(task_records(recorder, centralized), completed, sim_time_s)

    def fields(self) -> dict:
        """``tasks_completed`` .. the per-window throughput of ``metrics.json``."""
        sim_time = self.sim_time_s
        hours = sim_time / 3600.0 if sim_time else None
        durations = [d for _, d, _ in self.tasks]
        times = [t for t, _, _ in self.tasks]
        after = [t for t in times if t > WARMUP_S]
        warm_hours = (sim_time - WARMUP_S) / 3600.0 if sim_time and sim_time > WARMUP_S else None
        return {
            "tasks_completed": self.completed,
            "throughput_per_hour": (self.completed / hours) if hours else None,
            "warmup_s": WARMUP_S,
            "throughput_after_warmup_per_hour": (len(after) / warm_hours) if warm_hours
            else None,
            "time_to_task_mean_s": (sum(durations) / len(durations)) if durations else None,
            "time_to_task_median_s": _percentile(durations, 50.0),
            "time_to_task_p95_s": _percentile(durations, 95.0),
            "task_times_s": [round(t, 3) for t in times],
            "task_durations_s": [round(d, 3) for d in durations],
            **tasks_per_window(times, sim_time),
        }


@dataclass(frozen=True)
class FaultFigures:
    """The faults applied: the simulator's own log (complete), else the announcements the
    recorder heard (a listener may miss one).

    Attributes:
        log: every transition, ``fault``, ``kind``, ``phase``, ``robot``, ``t`` [s] (and
            ``x``, ``y`` [m] from the simulator).
        messages_dropped: messages the ``drop`` faults lost [-].
    """

    log: list
    messages_dropped: int

    @classmethod
    def of(cls, recorder: RunRecorder, sim: SimSummary) -> FaultFigures:
        sim_faults = sim.extras.get("faults") if isinstance(sim.extras, Mapping) else None
        log = (sim_faults or {}).get("log")
        if not isinstance(log, list):
            log = [{"fault": ev.fault, "kind": ev.kind, "phase": ev.phase,
                    "robot": ev.robot or None, "t": ev.t} for ev in recorder.fault_log]
        return cls(log, sum(((sim_faults or {}).get("messages_dropped") or {}).values()))

    @property
    def by_kind(self) -> dict[str, int]:
        """Faults started, by kind."""
        out: dict[str, int] = {}
        for entry in self.log:
            if isinstance(entry, Mapping) and entry.get("phase") == "start":
                out[str(entry.get("kind"))] = out.get(str(entry.get("kind")), 0) + 1
        return out

    def fields(self) -> dict:
        """``faults`` .. ``fault_messages_dropped`` of ``metrics.json``."""
        by_kind = self.by_kind
        return {"faults": sum(by_kind.values()), "faults_by_kind": by_kind,
                "fault_log": self.log, "fault_messages_dropped": self.messages_dropped}


def _coordination_fields(recorder: RunRecorder, centralized: bool,
                         sim_time_s: float | None) -> dict:
    """``coordinator_wait_s`` .. ``coordinator_lapses`` of ``metrics.json``."""
    events = recorder.reservation_events
    lapses = []
    for e in recorder.lapse_events:
        t = parse_stamp(e.get("t", ""))
        if t is not None:
            lapses.append({"robot": e.get("robot", ""), "t_s": round(t / NS_PER_S, 3),
                           "workstation": e.get("workstation", ""),
                           "reason": e.get("reason", "")})
    lapses.sort(key=lambda d: (d["t_s"], d["robot"]))
    return {
        "coordinator_wait_s": _spot_wait_s(events, sim_time_s) if centralized else None,
        "reservation_events": len(events),
        "reservation_conflicts": len(check_reservations(events)) if centralized else None,
        "coordinator_starts": recorder.coordinator_starts,
        "coordinator_lapses": lapses if centralized else None,
    }


def _per_robot(recorder: RunRecorder, sim: SimSummary, facts: RunFacts,
               comm: dict) -> tuple[dict, dict | None]:
    """``per_robot`` of ``metrics.json`` and the ``fleet`` (None without models)."""
    robots = recorder.robots
    per_robot = {ns: _robot_metrics(recorder.per_robot[ns], sim.robot(ns)) for ns in robots}
    for ns in robots:
        entry = comm["per_robot"][ns]
        per_robot[ns]["tasks"] = (len(recorder.per_robot[ns].tasks) if facts.centralized
                                  else per_robot[ns]["goals_reached"])
        if facts.centralized:  # its tasks, not its goals (a goal to a waiting spot is no task)
            per_robot[ns]["task_times_s"] = sorted(round(t, 3) for t, _, _ in
                                                   recorder.per_robot[ns].tasks)
        per_robot[ns]["comm_messages"] = entry["messages"]
        per_robot[ns]["comm_bytes"] = entry["bytes"]
    fleet = None
    if facts.models is not None:
        from swarm_scene.fleet import fleet_counts, model_label

        fleet = fleet_counts(facts.models)
        for ns, model in zip(robots, facts.models, strict=True):
            per_robot[ns]["robot"] = model_label(model)
    return per_robot, fleet


def _task_intervals(rec: RobotRecord, facts: RunFacts) -> list[tuple[float, float, tuple]]:
    """(start [s], end [s], workstation x, y [m]) of each task a robot completed: under a
    coordinator its task records (from its assignment to its ``done``); decentralized its goals
    reached (from the goal taking effect to reaching it, at the workstation it reached)."""
    if facts.centralized:
        where = facts.workstations or {}
        return [(t - d, t, tuple(where[ws])) for t, d, ws in rec.tasks if ws in where]
    out = []
    for goal, end in rec.reached_at.items():
        ttg, xy = rec.reached.get(goal), rec.goal_xy.get(goal)
        if ttg is not None and xy is not None:
            out.append((end - ttg, end, xy))
    return out


def _waiting(recorder: RunRecorder, sim: SimSummary, facts: RunFacts) -> dict[str, float] | None:
    """robot -> [s] it waited during its completed tasks (:mod:`swarm_metrics.waiting`), or None
    without the simulator's track or a map."""
    extras = sim.extras if isinstance(sim.extras, Mapping) else {}
    track = extras.get("track")
    if not facts.map_path or not isinstance(track, Mapping) or not track.get("xy"):
        return None
    import numpy as np

    from swarm_common.errors import InputError
    from swarm_metrics.waiting import DistanceField, waiting_s
    from swarm_scene.map_io import load_map

    try:
        occ = load_map(facts.map_path)
        xy = np.asarray(track["xy"], dtype=float)  # (T, N, 2)
    except (InputError, ValueError, OSError):
        return None
    if xy.ndim != 3 or xy.shape[1] != len(recorder.robots):
        return None
    field = DistanceField(occ.data, occ.resolution, occ.origin)
    period = float(track.get("period_s") or 1.0)
    return {ns: round(waiting_s(xy[:, i], _task_intervals(recorder.per_robot[ns], facts),
                                field, period), 3)
            for i, ns in enumerate(recorder.robots)}


def _scene_fields(sim: SimSummary, facts: RunFacts) -> dict:
    """``spawn``, ``world_skipped`` and the standstills of ``metrics.json``."""
    extras = sim.extras if isinstance(sim.extras, Mapping) else {}
    places = {name: [tuple(xy), *map(tuple, (facts.holding or {}).get(name, []))]
              for name, xy in (facts.workstations or {}).items()}
    standstills = label_standstills(extras.get("standstills"), places)
    spawn, skipped = extras.get("spawn"), extras.get("world_skipped")
    return {
        "spawn": spawn if isinstance(spawn, str) else None,
        "world_skipped": [str(e) for e in skipped] if isinstance(skipped, list) else None,
        "standstills": standstills,
        "standstill_s": round(sum(finite_float(e.get("duration_s")) or 0.0
                                  for e in standstills), 3),
    }


def aggregate(recorder: RunRecorder, sim_summary: SimSummary, facts: RunFacts) -> dict:
    """The ``--metrics`` dict of a run (docs/reference/contract.md#s6).

    Simulator figures (``sim_time_s``, ``rtf``, ticks, collisions, separation, late ticks,
    distances) come from the simulator's summary; where it lacks them, from the recorder's
    ``/clock`` and ``/swarm/events`` (collisions, late ticks) or None.  Built from the typed
    pieces :class:`Timing`, :class:`TaskFigures` and :class:`FaultFigures`.

    Args:
        recorder: the run's recorder.
        sim_summary: from :func:`load_sim_summary`.
        facts: what the orchestrator knows of the run (:class:`RunFacts`).

    Returns:
        A JSON-serialisable dict with the keys of docs/reference/contract.md#s6 (None where
        unknown), in the contract's order.
    """
    sim, robots = sim_summary, recorder.robots
    timing = Timing.of(recorder, sim, facts.wall_time_s)
    comm = _comm(recorder, facts.map_deliveries, timing.sim_time_s)
    per_robot, fleet = _per_robot(recorder, sim, facts, comm)
    waiting = _waiting(recorder, sim, facts)
    if waiting is not None:
        for ns in robots:
            per_robot[ns]["waiting_s"] = waiting[ns]
    reached = sum(r["goals_reached"] for r in per_robot.values())
    tasks = TaskFigures.of(recorder, facts.centralized, reached, timing.sim_time_s)
    scene = _scene_fields(sim, facts)
    ttgs = [t for ns in robots for t in _times_to_goal(recorder.per_robot[ns])]
    late = _late_ticks(recorder, sim)
    waits = sum(r.goal_wait_timeouts_total for r in recorder.per_robot.values())
    late_goals = sum(recorder.per_robot[ns].late_goals for ns in robots)
    resources = facts.resources or {}
    metrics = {
        "robots": len(robots),
        **({"fleet": fleet} if fleet is not None else {}),
        "world": facts.world,
        "seed": facts.seed,
        "coordination": facts.coordination,
        "spawn": scene["spawn"],
        "world_skipped": scene["world_skipped"],
        **timing.fields(facts.wall_time_s),
        "spawn_to_ready_s": recorder.spawn_to_ready_s(),
        "goals_reached": reached,
        "goals_aborted": sum(r["goals_aborted"] for r in per_robot.values()),
        "goals_at_another_workstation": sum(r["goals_at_another_workstation"]
                                            for r in per_robot.values()),
        **tasks.fields(),
        "tasks_per_robot": tasks_per_robot([per_robot[ns]["tasks"] for ns in robots]),
        "workstations": workstation_table(recorder, facts.workstations or {}),
        "standstills": scene["standstills"],
        "standstill_s": scene["standstill_s"],
        "collisions": _collisions(recorder, sim),
        "min_separation_m": finite_float(sim.min_separation_m),
        "mean_time_to_goal_s": (sum(ttgs) / len(ttgs)) if ttgs else None,
        "holding_time_s": sum((r["holding_time_s"] for r in per_robot.values()), 0.0),
        "waiting_s": None if waiting is None else round(sum(waiting.values()), 3),
        "waiting_per_task_s": (None if waiting is None or not tasks.completed
                               else round(sum(waiting.values()) / tasks.completed, 3)),
        "late_ticks": late,
        "goal_wait_timeouts": waits,
        "late_goals": late_goals,
        "reproducible": None if late is None else (
            late == 0 and waits == 0 and facts.restarts == facts.fault_restarts
            and late_goals == 0),
        **_coordination_fields(recorder, facts.centralized, timing.sim_time_s),
        "comm_messages_per_s": comm["messages_per_s"],
        "comm_bytes_per_s": comm["bytes_per_s"],
        "comm": comm,
        "cpu_percent": resources.get("cpu_percent"),
        "peak_rss_mb_per_robot": resources.get("peak_rss_mb_per_robot"),
        "sim_peak_rss_mb": resources.get("sim_peak_rss_mb"),
        "restarts": facts.restarts,
        **FaultFigures.of(recorder, sim).fields(),
        "unresponsive_events": recorder.fault_events,
        "per_robot": per_robot,
    }
    if facts.extra:
        metrics.update(facts.extra)
    return metrics
