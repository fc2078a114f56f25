"""A commander that asks the coordinator for its tasks (``swarm-up --coordination centralized``).

:class:`CoordinatedRunner` drives one robot's :class:`~swarm_commander.robot_navigator.
BasicNavigator` like :class:`swarm_commander.cli.CommanderRunner`, but it does not choose: when
its robot is ready, and whenever a workstation goal ends, it sends a request on
``/swarm/coordinator/request`` and drives to what the coordinator answers on
``/<ns>/coordinator/assignment`` (:mod:`swarm_common.coordination`): a workstation (``go``) or a
waiting spot (``wait``). It connects to its navigator (creates ``goal_pose``, which opens the
navigator's start gate under swarm-up) only once it and the coordinator hear each other, since
the coordinator answers the first requests once every robot has asked. At a waiting spot it
tells its navigator that no next goal is coming (a cancel with no goal running, so the
navigator's next tick does not wait) and waits for the coordinator to hand it the workstation.

**In the lockstep** (docs/ARCHITECTURE.md, "Coordination"; no wall-clock timeout decides
anything simulated): its navigator holds the tick at which a goal ended (``hold_goal_end``) until
the commander gives its word; for a ``done`` request the word is ``navigator/goal_coming``, said
once the coordinator has acknowledged the request (``ack``), so the coordinator has every
request of a tick before the simulator moves on, and answers them together. A workstation
handed over unasked (``reply_to`` 0) is confirmed (``delivered``) once the navigator reports the
goal pending (``pending_goal_id`` in ``nav_status``): the coordinator holds the answers the
simulator waits for until then, so the hand-over takes effect at a fixed tick.

**When the coordinator is down** (a ``kill-coordinator`` fault of the run's schedule,
``CoordinatedConfig.outages``; tested in ``tests/test_e2e_coordination.py``):

1. The robot finishes the goal it has; nothing on the way depends on the coordinator.
2. A goal that ends when the coordinator will not see the next tick (from one tick before the
   kill to the restart) is reported to no one: the robot stays where it is, with a goal to its
   own docking pose stamped with the restart (so it takes effect at a fixed tick), and reports
   the task when that goal ends; without a restart it stops for good. A robot waiting at a spot
   keeps waiting.
3. A coordinator that comes (back) up publishes a new epoch on ``/swarm/coordinator/state``;
   every commander then reports what it holds and waits for (or re-sends its open request), and
   the coordinator rebuilds its tables from these reports before it answers anyone; simulated
   time waits at the restart until it serves.

A request with no answer is sent again after 1 s (wall), then 2, 4, 8, 8, ... s (only a lost
message or a crashed coordinator needs it: the copies change nothing simulated and are not
counted in the communication load).
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass

from geometry_msgs.msg import PoseStamped
from rclpy.clock import Clock, ClockType
from rclpy.task import Future
from std_msgs.msg import String
from std_srvs.srv import Trigger

from swarm_commander.robot_navigator import BasicNavigator, TaskResult
from swarm_common import topics
from swarm_common.coordination import (
    COORDINATOR_NODE,
    Assignment,
    ContractError,
    Request,
    decode_assignment,
    decode_state,
    encode_request,
    spot_resource,
    workstation_resource,
)
from swarm_common.geometry import yaw_to_quaternion
from swarm_common.stamps import NS_PER_S
from swarm_ros.latched import REMATCH_S, LatchedReader
from swarm_ros.qos import publisher, subscription

_OUTCOME = {TaskResult.SUCCEEDED: "succeeded", TaskResult.FAILED: "failed",
            TaskResult.CANCELED: "canceled"}


@dataclass(frozen=True)
class CoordinatedConfig:
    """Settings of a coordinated commander.

    Attributes:
        wait_timeout: [s] wall: how long to wait for the navigator's first ``nav_status``.
        retry_first: [s] wall: first wait for an answer before the request is sent again.
        retry_max: [s] wall: the longest wait between two sends (the backoff doubles up to it).
        retry_ready: [s] wall: first wait before the first request (``ready``) is sent again:
            the coordinator answers it only once every robot is ready.
        poll_period: [s] wall: period of the runner's timer.
        outages: the run's ``kill-coordinator`` windows, ``(start_ns, end_ns)`` [ns] simulated
            (:func:`swarm_common.faults.coordinator_outages`; end None: not restarted).
        period_ns: [ns] the simulator's control tick.
        resend_goal: [s] wall: an unconfirmed hand-over is given to the navigator again after
            this long (a navigator restarted meanwhile lost it).
    """

    wait_timeout: float = 30.0
    retry_first: float = 1.0
    retry_max: float = 8.0
    retry_ready: float = 8.0
    poll_period: float = 0.1
    outages: tuple[tuple[int, int | None], ...] = ()
    period_ns: int = NS_PER_S // 10
    resend_goal: float = 3.0


class CoordinatedRunner:
    """One robot's commander in centralized mode (see the module doc).

    Args:
        navigator: the robot's :class:`BasicNavigator`; the runner adds its publishers,
            subscriptions, a service client and a wall-clock timer to it.
        cfg: the settings.
        emit: called with each output line (a task's outcome, a retry, the summary).
    """

    def __init__(self, navigator: BasicNavigator, cfg: CoordinatedConfig = CoordinatedConfig(),
                 emit: Callable[[str], None] = print):
        self.nav = navigator
        self.cfg = cfg
        self.emit = emit
        self.label = navigator.get_namespace().strip("/") or navigator.get_name()
        self.tasks = self.reached = self.failed = self.canceled = 0
        self.retries = 0
        self.error: str | None = None
        self.finished = Future()
        self._started = False
        self._deadline: float | None = None  # from the first timer call (CommanderRunner's)
        self._epoch: str | None = None
        self._seq = 0
        self._pending: Request | None = None
        self._next_send = 0.0
        self._backoff = cfg.retry_first
        self._current: Assignment | None = None
        self._wait_since_ns = 0  # when the current wait began (its place in the queue)
        self._unsent: Assignment | None = None
        self._applied = 0  # highest assignment seq applied in this epoch
        self._resync = False  # a new coordinator is to be told what we hold
        self._first_start_ns: int | None = None
        self._acked = False  # the coordinator has the open request (navigator told)
        self._deferred: tuple[str, str] | None = None  # (outcome, target) of an unsent done
        self._staying = False  # a goal that holds the robot through a coordinator outage runs
        self._deliver: tuple[int, str, float] | None = None  # (seq, goal id, wall) unconfirmed
        navigator.on_task_complete = self._on_task_complete
        self._req_pub = publisher(navigator, String, topics.COORDINATOR_REQUEST)
        self._assignment_sub = subscription(navigator, String, topics.ASSIGNMENT,
                                            self._on_assignment,
                                            qos=topics.ASSIGNMENT_READER_QOS)
        self._state_reader = LatchedReader(navigator, String, topics.COORDINATOR_STATE,
                                           self._on_state)
        self._decline = navigator.create_client(Trigger, topics.CANCEL_SERVICE)
        self._coming = navigator.create_client(Trigger, topics.GOAL_COMING_SERVICE)
        self._timer = navigator.create_timer(
            cfg.poll_period, self._on_timer, clock=Clock(clock_type=ClockType.STEADY_TIME))

    # -- public -----------------------------------------------------------------------------
    @property
    def started(self) -> bool:
        """True once the robot asked for its first task."""
        return self._started

    @property
    def coordinator_seen(self) -> bool:
        """True once a coordinator's ``state`` was received."""
        return self._epoch is not None

    def stop(self) -> None:
        """Stop driving: cancel the timer and detach from the navigator."""
        self._timer.cancel()
        if self.nav.on_task_complete == self._on_task_complete:
            self.nav.on_task_complete = None

    def summary(self) -> str:
        """The summary line (tasks, outcomes, re-sent requests)."""
        now = self.nav.status_stamp_ns or 0
        elapsed = (now - self._first_start_ns) / NS_PER_S if self._first_start_ns else 0.0
        return (f"[{self.label}] summary: {self.tasks} tasks: {self.reached} reached, "
                f"{self.failed} failed, {self.canceled} canceled in {elapsed:.1f} s (sim); "
                f"{self.retries} requests re-sent")

    # -- callbacks --------------------------------------------------------------------------
    def _on_timer(self) -> None:
        if self.finished.done():
            return
        now = time.monotonic()
        if self._deadline is None:
            self._deadline = now + self.cfg.wait_timeout
        if not self.nav.connected:
            # Connect (the navigator's start gate opens) only once the coordinator hears our
            # requests and we hear its answers: at the start it answers once every robot asked,
            # and a request or answer sent before discovery matched it would be lost.
            linked = self._epoch is not None and self._heard_by_coordinator() \
                and self._assignment_sub.get_publisher_count() > 0
            if linked or now >= self._deadline:
                if not linked:
                    self.emit(f"[{self.label}] not linked to the coordinator after "
                              f"{self.cfg.wait_timeout:g} s; connecting to the navigator anyway")
                self.nav.connect()
                self._deadline = now + self.cfg.wait_timeout
            return
        if not self._started:
            if self.nav.navigator_ready and self._epoch is not None \
                    and self._heard_by_coordinator():
                self._started = True
                self._request("ready")
            elif now >= self._deadline and not self.nav.navigator_ready:
                code, why = self.nav.not_ready_reason(self.cfg.wait_timeout)
                self.error = f"{self.label}: {why}"
                self.stop()
                self.finished.set_result(code)
            return
        if self._resync and self._heard_by_coordinator():
            self._resync_now()
        if self._unsent is not None:
            self._drive(self._unsent)
        self._check_delivery(now)
        if self._pending is not None and now >= self._next_send:
            self.retries += 1
            self.emit(f"[{self.label}] no answer from the coordinator to request "
                      f"{self._pending.seq} ({self._pending.kind}); sending it again "
                      f"(next try in {min(2 * self._backoff, self.cfg.retry_max):g} s)")
            self._send(self._pending)
            self._backoff = min(2 * self._backoff, self.cfg.retry_max)
            self._next_send = now + self._backoff

    def _on_state(self, msg: String) -> None:
        try:
            epoch = decode_state(msg.data)
        except ContractError:
            return
        if epoch == self._epoch:
            return
        old, self._epoch, self._applied = self._epoch, epoch, 0
        if old is not None and self._started:
            self._resync = True  # done by the timer once the new coordinator hears us

    def _resync_now(self) -> None:
        """A new coordinator: re-send the open request, or report what we hold."""
        self._resync = False
        if self._pending is not None:
            old_req = self._pending
            self._pending = self._make(old_req.kind, old_req.outcome, old_req.target,
                                       seq=old_req.seq)
            self._send(self._pending)
            self._backoff = self.cfg.retry_first
            self._next_send = time.monotonic() + self.cfg.retry_first
        else:
            self._send(self._make("report"))

    def _on_assignment(self, msg: String) -> None:
        try:
            a = decode_assignment(msg.data)
        except ContractError as exc:
            self.nav.get_logger().warning(f"dropped a malformed assignment: {exc}",
                                          throttle_duration_sec=5.0)
            return
        if a.robot != self.label:
            return
        if a.kind == "ack":  # the coordinator has the request: the navigator may go on
            req = self._pending
            if req is not None and a.reply_to == req.seq and req.kind == "done" \
                    and not self._acked:
                self._acked = True
                self._coming.call_async(Trigger.Request())
            return
        if a.epoch != self._epoch:  # its state message may still be on the way
            self._epoch, self._applied = a.epoch, 0
        if a.seq <= self._applied:
            return
        self._applied = a.seq
        if self._pending is not None and a.reply_to == self._pending.seq:
            self._pending = None
        if self._first_start_ns is None:
            self._first_start_ns = a.task_start_ns
        self._drive(a)
        if a.reply_to == 0:  # unasked: the coordinator waits for its delivery
            self._deliver = (a.seq, self.nav.current_goal_id(), time.monotonic())
            self._check_delivery(time.monotonic())

    def _on_task_complete(self, result: TaskResult) -> None:
        cur = self._current
        if cur is None:
            return
        if self._staying:  # the coordinator is back: report the task that ended meanwhile
            self._staying = False
            outcome, target = self._deferred
            self._deferred = None
            self._request("done", outcome, target)
            return
        if cur.kind == "wait":
            # At the spot (or not reachable): no next goal until the coordinator hands over.
            if self._decline.service_is_ready():
                self._decline.call_async(Trigger.Request())
            return
        self.tasks += 1
        now = self.nav.status_stamp_ns or 0
        took = (now - cur.task_start_ns) / NS_PER_S
        head = f"[{self.label}] task {self.tasks}:"
        if result == TaskResult.SUCCEEDED:
            self.reached += 1
            self.emit(f"{head} reached {cur.target} in {took:.1f} s (sim)")
        else:
            feedback = self.nav.getFeedback()
            reason = feedback.reason if feedback is not None and feedback.reason else "no reason"
            if result == TaskResult.CANCELED:
                self.canceled += 1
            else:
                self.failed += 1
            self.emit(f"{head} failed to reach {cur.target} after {took:.1f} s (sim): {reason}")
        outcome = _OUTCOME.get(result, "failed")
        restart = self._outage(now)
        if restart is False:
            self._request("done", outcome, cur.target)
            return
        # the coordinator will not see the next tick: tell no one, stay until it is back
        self._deferred = (outcome, cur.target)
        if restart is None:  # not restarted: no next goal, ever
            self.emit(f"[{self.label}] the coordinator is down for good; stopping here")
            if self._decline.service_is_ready():
                self._decline.call_async(Trigger.Request())
            return
        self.emit(f"[{self.label}] the coordinator is down until t = {restart / NS_PER_S:g} s; "
                  "staying here")
        self._staying = True
        self.nav.go_to_pose_at(_pose_msg(cur.pose), restart)

    # -- helpers ----------------------------------------------------------------------------
    def _drive(self, a: Assignment) -> None:
        prev = self._current
        if a.kind == "wait" and not (
                prev is not None and prev.kind == "wait" and prev.waits_for == a.waits_for
                and prev.task_start_ns == a.task_start_ns):
            self._wait_since_ns = a.stamp_ns  # a new wait (a move to another spot is not)
        self._current = a
        if self.nav.go_to_pose_at(_pose_msg(a.pose), a.stamp_ns):
            self._unsent = None
        else:  # the navigator is gone for now: the timer tries again
            self._unsent = a

    def _holdings(self) -> tuple[tuple[str, ...], str, int]:
        a = self._current
        if a is None:
            return (), "", 0
        if a.kind == "go":
            return (workstation_resource(a.target),), "", 0
        # Its place in the queue is when the wait began, not when it was moved to this spot
        # (parking to holding spot): reported with the move's stamp, a robot that had waited on
        # loader5's holding spot since 105 s came after one parked in the hall since 124.5 s,
        # and a restarted coordinator gave loader5 to the one in the hall (10 robots, seed 2).
        return (spot_resource(a.target),), a.waits_for, self._wait_since_ns

    def _make(self, kind: str, outcome: str = "", target: str = "",
              seq: int | None = None, delivered: int = 0) -> Request:
        if seq is None and kind != "delivered":
            self._seq += 1
            seq = self._seq
        seq = self._seq if seq is None else seq
        holds, waits_for, since = self._holdings()
        a = self._current
        return Request(robot=self.label, seq=seq, kind=kind,
                       stamp_ns=self.nav.status_stamp_ns or 0, outcome=outcome, target=target,
                       holds=holds, waits_for=waits_for, since_ns=since,
                       task_start_ns=a.task_start_ns if a is not None else 0,
                       delivered=delivered)

    def _outage(self, t_ns: int):
        """Whether a goal that ended at ``t_ns`` falls in a coordinator outage: False if not
        (the coordinator will see tick ``t_ns + period``); else the outage's end [ns], or None
        if it never ends. The coordinator is killed before the simulator publishes the kill's
        tick, so a request of the tick before it would never be answered either."""
        for start, end in self.cfg.outages:
            if t_ns + self.cfg.period_ns >= start and (end is None or t_ns < end):
                return end
        return False

    def _check_delivery(self, now: float) -> None:
        """Confirm an unasked assignment once the navigator reports its goal pending (or
        running); give it to the navigator again after ``resend_goal`` s without."""
        if self._deliver is None:
            return
        seq, goal_id, since = self._deliver
        status = self.nav.last_status
        if goal_id and status is not None and goal_id in (status.pending_goal_id,
                                                          status.goal_id):
            self._deliver = None
            self._send(self._make("delivered", delivered=seq))
        elif now - since >= self.cfg.resend_goal and self._current is not None:
            self._drive(self._current)
            self._deliver = (seq, self.nav.current_goal_id(), now)

    def _request(self, kind: str, outcome: str = "", target: str = "") -> None:
        self._acked = False
        self._pending = self._make(kind, outcome, target)
        self._send(self._pending)
        self._backoff = self.cfg.retry_first
        if kind == "ready":  # the coordinator answers once every robot is ready: wait longer
            self._backoff = self.cfg.retry_ready
        self._next_send = time.monotonic() + self._backoff

    def _heard_by_coordinator(self) -> bool:
        """Whether our request publisher is matched with the coordinator's subscription (a
        request published before discovery matched it would be lost)."""
        infos = self.nav.get_subscriptions_info_by_topic(topics.COORDINATOR_REQUEST.name)
        return (any(i.node_name == COORDINATOR_NODE for i in infos)
                and self._req_pub.get_subscription_count() >= len(infos))

    def _send(self, req: Request) -> None:
        self._req_pub.publish(String(data=encode_request(req)))


def coordinated_config(faults: str | None, wait_timeout: float = 30.0) -> CoordinatedConfig:
    """The settings of a coordinated commander of a run whose fault schedule is the file (or
    inline SPEC) ``faults`` (None: no faults): the coordinator's outages come from it.

    Raises:
        InputError: the schedule is malformed (names ``--faults``).
    """
    outages = ()
    if faults:
        from swarm_common.errors import InputError
        from swarm_common.faults import coordinator_outages

        try:
            outages = coordinator_outages(faults)
        except InputError as exc:
            raise InputError(f"--faults: {exc}") from None
    return CoordinatedConfig(wait_timeout=wait_timeout, outages=outages)


def _pose_msg(pose: tuple[float, float, float]) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.pose.position.x, msg.pose.position.y = float(pose[0]), float(pose[1])
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = yaw_to_quaternion(float(pose[2]))
    return msg


def wait_for_coordinator(node, timeout_s: float, spin_once: Callable[[float], None],
                         rematch_s: float = REMATCH_S) -> bool:
    """Spin until a coordinator's latched ``state`` is received (before commanders exist, so
    that the simulator's start gate opens only with the coordinator there).

    Args:
        node: a node to create the temporary reader on (a
            :class:`swarm_ros.latched.LatchedReader`: made again every ``rematch_s`` until the
            state arrives, eProsima/Fast-DDS#3822).
        timeout_s: [s] wall.
        spin_once: spins the executor that holds ``node`` once, with a timeout [s].
        rematch_s: [s] wall, > 0 (:data:`swarm_ros.latched.REMATCH_S`).

    Returns:
        True once seen, False after ``timeout_s``.
    """
    seen = []
    reader = LatchedReader(node, String, topics.COORDINATOR_STATE, seen.append,
                           rematch_s=rematch_s)
    deadline = time.monotonic() + timeout_s
    try:
        while not seen and time.monotonic() < deadline:
            spin_once(0.1)
    finally:
        reader.destroy()
    return bool(seen)
