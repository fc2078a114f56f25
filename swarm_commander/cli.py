"""``swarm-commander NS``: one robot's commander (docs/reference/contract.md#s5-commander).

::

    swarm-commander Srobot3 [--world NAME|PATH] [--route random|PATH.yaml] [--loops N]
                    [--seed S] [--wait-timeout SEC] [--service-time SEC] [--name-prefix P]
                    [--ros-args ...]

It waits for the robot's navigator (its first ``nav_status``), then visits the stops of the
route, one task per stop, and prints one line per task::

    [Srobot3] task 4: reached loader2 in 41.2 s (sim)
    [Srobot3] task 5: reached loader4 in 63.0 s (sim), sent to loader3 (taken)
    [Srobot3] task 6: failed to reach loader1 after 0.4 s (sim): goal inside an obstacle

and, at the end or on Ctrl-C, a summary line. A navigator holding for a taken workstation may
take another free one of its kind instead (its ``swap_range``): the line names the one reached,
and the next stop is skipped if it is that one (the robot stands on it). At a workstation
reached the robot stays for the service time (``--service-time``, the world's ``service_time``):
its next goal is stamped that much after the arrival. ``NS`` may also be a
robot number, joined to ``--name-prefix`` (``3`` → ``Srobot3``). The node is
``/<NS>/commander``; it uses simulated time unless ``--ros-args -p use_sim_time:=false`` says
otherwise.

:class:`CommanderRunner` is the commander without the process around it: it owns the route state
and is driven by its navigator node's callbacks (a wall-clock timer and the end of each task),
never by a blocking loop, so the commanders of many robots can share one executor.
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

from geometry_msgs.msg import PoseStamped
from rclpy._rclpy_pybind11 import RCLInvalidROSArgsError
from rclpy.clock import Clock, ClockType
from rclpy.executors import SingleThreadedExecutor
from rclpy.logging import LoggingSeverity
from rclpy.parameter import Parameter
from rclpy.task import Future
from rclpy.utilities import remove_ros_args

from swarm_commander.robot_navigator import BasicNavigator, TaskResult
from swarm_commander.route import (
    FixedRoute,
    RandomRoute,
    RouteStop,
    build_route,
    visits,
    world_service_time,
)
from swarm_common import cli
from swarm_common.errors import EXIT_OK, InputError, run_cli
from swarm_common.geometry import pose2d, yaw_to_quaternion
from swarm_common.stamps import NS_PER_S
from swarm_ros.session import node_session

PROG = "swarm-commander"
NODE_NAME = "commander"


@dataclass(frozen=True)
class CommanderConfig:
    """Settings of one robot's commander.

    Attributes:
        loops: loops over the route; 0 = forever.
        wait_timeout: [s] wall: how long to wait for the navigator's first ``nav_status`` (and
            its ``goal_pose`` reader), from the runner's first step in a spinning executor.
        poll_period: [s] wall: period of the runner's timer while something is due (a goal
            to send again, a navigator heard but not yet subscribed to ``goal_pose``).
        idle_period: [s] wall: period of the runner's timer otherwise (the first status and a
            task's end come as events; the timer then only checks ``wait_timeout``).
        service_time: [s] simulated: how long the robot stays at a workstation it has reached
            (the world's ``service_time``): the next goal is stamped that much after the
            arrival, and the navigator applies a goal at its first tick after the stamp.
    """

    loops: int = 0
    wait_timeout: float = 30.0
    poll_period: float = 0.1
    idle_period: float = 1.0
    service_time: float = 0.0


class CommanderRunner:
    """One robot's commander, driven by its navigator node's callbacks.

    It adds a wall-clock timer to ``navigator`` and sets ``navigator.on_task_complete``; whoever
    spins the node (alone, or with other robots' nodes in one executor) drives it. When the route
    is done, or the navigator never answers, :attr:`finished` completes with the exit code
    (0 done; 2 no ``nav_status`` within ``cfg.wait_timeout``; 1 a status but no ``goal_pose``
    subscriber) and :attr:`error` holds the one-line reason.

    Args:
        navigator: the robot's :class:`BasicNavigator` (its namespace is the robot's).
        route: where the stops come from (:class:`RandomRoute` or :class:`FixedRoute`).
        cfg: the settings.
        emit: called with each output line (a task's outcome, the summary).
    """

    def __init__(self, navigator: BasicNavigator, route: RandomRoute | FixedRoute,
                 cfg: CommanderConfig, emit: Callable[[str], None] = print):
        self.nav = navigator
        self.cfg = cfg
        self.emit = emit
        self.label = navigator.get_namespace().strip("/") or navigator.get_name()
        self.tasks = 0
        self.reached = 0
        self.failed = 0
        self.canceled = 0
        self.skipped = 0
        """Stops skipped because the robot already stood there (it took that workstation)."""
        self.error: str | None = None
        """The one-line error when the commander gave up (no navigator), else None."""
        self.finished = Future()
        self._visits = visits(route, cfg.loops)
        self._stops = route.stops
        self._took: str | None = None  # the stop the last task took instead of the one sent
        self._started = False
        self._pending: RouteStop | None = None
        self._current: RouteStop | None = None
        self._task_start_ns = 0
        self._first_start_ns: int | None = None
        self._not_before_ns = 0  # [ns] simulated: the next goal's earliest stamp (service)
        # wait_timeout counts from the first step, when an executor spins the node: a group
        # process makes all its nodes before it spins any (500 commanders: over 2 minutes)
        self._deadline: float | None = None
        navigator.on_task_complete = self._on_task_complete
        navigator.on_first_status = self._on_timer
        self._period = 0.0
        self._timer = None
        self._retime()

    @property
    def clock_label(self) -> str:
        """``"sim"`` when the node runs on simulated time, else ``"wall"``."""
        return "sim" if self.nav.get_parameter("use_sim_time").value else "wall"

    def summary(self) -> str:
        """The summary line: tasks, outcomes, and the time since the first goal."""
        elapsed = 0.0
        if self._first_start_ns is not None:
            elapsed = (self._now_ns() - self._first_start_ns) / 1e9
        unfinished = ", 1 unfinished" if self._current is not None else ""
        return (f"[{self.label}] summary: {self.tasks} tasks: {self.reached} reached, "
                f"{self.failed} failed, {self.canceled} canceled{unfinished} in {elapsed:.1f} s "
                f"({self.clock_label})")

    @property
    def started(self) -> bool:
        """True once the navigator answered (tasks may have been sent)."""
        return self._started

    def stop(self) -> None:
        """Stop driving: cancel the timer and detach from the navigator (the goal runs on)."""
        self._timer.cancel()
        if self.nav.on_task_complete == self._on_task_complete:
            self.nav.on_task_complete = None
        if self.nav.on_first_status == self._on_timer:
            self.nav.on_first_status = None

    def _retime(self) -> None:
        """The timer's period: ``poll_period`` while something is due, else ``idle_period``
        (:class:`CommanderConfig`). One robot's timer is cheap; 500 commanders of one group
        process at 10 Hz were 5,000 callbacks a second, most of them with nothing to do."""
        if self.finished.done():
            return
        due = self._pending is not None or (not self._started and self.nav.nav_status_received)
        period = self.cfg.poll_period if due else max(self.cfg.poll_period, self.cfg.idle_period)
        if period == self._period:
            return
        if self._timer is not None:
            self.nav.destroy_timer(self._timer)
        self._period = period
        self._timer = self.nav.create_timer(
            period, self._on_timer, clock=Clock(clock_type=ClockType.STEADY_TIME))

    # -- callbacks

    def _on_timer(self) -> None:
        self._step()
        self._retime()

    def _on_task_complete(self, result: TaskResult) -> None:
        self._step()
        self._retime()

    def _step(self) -> None:
        if self.finished.done():
            return
        if not self._started:
            if self.nav.navigator_ready:
                self._started = True
            elif self._deadline is None:
                self._deadline = time.monotonic() + self.cfg.wait_timeout
                return
            elif time.monotonic() >= self._deadline:
                code, why = self.nav.not_ready_reason(self.cfg.wait_timeout)
                self._fail(code, f"{self.label}: {why}")
                return
            else:
                return
        if self._current is not None:
            if not self.nav.task_complete():
                return
            self._report(self.nav.getResult())
            self._current = None
        while self._pending is None:
            visit = next(self._visits, None)
            if visit is None:
                self._finish()
                return
            if visit[1].name == self._took:  # the last task took this one: we stand on it
                self._took = None
                self.skipped += 1
                continue
            self._pending = visit[1]
        if self.nav.go_to_pose_at(_pose_msg(self._pending), self._not_before_ns):
            self._current, self._pending = self._pending, None
            self.tasks += 1
            self._task_start_ns = max(self._now_ns(), self._not_before_ns)
            if self._first_start_ns is None:
                self._first_start_ns = self._task_start_ns
        # else: the navigator is gone for now; the timer retries

    def _report(self, result: TaskResult) -> None:
        elapsed = (self._now_ns() - self._task_start_ns) / 1e9
        head = f"[{self.label}] task {self.tasks}:"
        name, clock = self._current.name, self.clock_label
        feedback = self.nav.getFeedback()
        if result == TaskResult.SUCCEEDED:
            self.reached += 1
            # the robot stays docked for the service: the next goal takes effect after it
            arrived = self.nav.status_stamp_ns
            if arrived is not None and self.cfg.service_time > 0.0:
                self._not_before_ns = arrived + round(self.cfg.service_time * NS_PER_S)
            stop = self._reached_stop(feedback)
            self._took = stop.name if stop is not self._current else None
            sent = f", sent to {name} (taken)" if self._took else ""
            self.emit(f"{head} reached {stop.name} in {elapsed:.1f} s ({clock}){sent}")
            return
        self._took = None
        reason = feedback.reason if feedback is not None and feedback.reason else "no reason given"
        if result == TaskResult.CANCELED:
            self.canceled += 1
            self.emit(f"{head} canceled on the way to {name} after {elapsed:.1f} s ({clock}): "
                      f"{reason}")
        else:
            self.failed += 1
            self.emit(f"{head} failed to reach {name} after {elapsed:.1f} s ({clock}): {reason}")

    def _reached_stop(self, feedback) -> RouteStop:
        """The stop the navigator reached: the one sent, unless it reports a goal 1 cm or more
        away from it (it took another workstation); then the route's stop within 1 cm of that
        goal, or, if the route has none there, a stop named by the goal's x, y [m]."""
        goal = feedback.goal if feedback is not None else None
        if goal is None or math.dist(goal[:2], self._current.pose[:2]) < 0.01:
            return self._current
        near = min(self._stops, key=lambda s: math.dist(goal[:2], s.pose[:2]))
        if math.dist(goal[:2], near.pose[:2]) < 0.01:
            return near
        return RouteStop(f"({goal[0]:.2f}, {goal[1]:.2f})", pose2d(*goal))

    def _finish(self) -> None:
        self.stop()
        self.finished.set_result(EXIT_OK)

    def _fail(self, code: int, message: str) -> None:
        self.error = message
        self.stop()
        self.finished.set_result(code)

    def _now_ns(self) -> int:
        return self.nav.get_clock().now().nanoseconds


def _pose_msg(stop: RouteStop) -> PoseStamped:
    msg = PoseStamped()
    msg.header.frame_id = "map"
    msg.pose.position.x, msg.pose.position.y = float(stop.pose[0]), float(stop.pose[1])
    o = msg.pose.orientation
    o.x, o.y, o.z, o.w = yaw_to_quaternion(float(stop.pose[2]))
    return msg


def _wait_for_coordinator(ns: str, executor, timeout_s: float) -> None:
    """Wait for the coordinator before the commander's node exists (its navigator's start
    gate opens when a commander connects: the coordinator must be there by then)."""
    from rclpy.node import Node

    from swarm_commander.coordinated import wait_for_coordinator

    watch = Node("coordinator_watch", namespace=ns)
    executor.add_node(watch)
    try:
        if not wait_for_coordinator(watch, timeout_s,
                                    lambda t: executor.spin_once(timeout_sec=t)):
            _emit(f"[{ns}] no coordinator after {timeout_s:g} s; starting anyway")
    finally:
        executor.remove_node(watch)
        watch.destroy_node()


def _parser() -> argparse.ArgumentParser:
    p = cli.ArgumentParser(prog=PROG, description="Drive one robot through the world's "
                           "workstations (nav2 simple-commander style), looping, and print each "
                           "arrival.")
    p.add_argument("ns", metavar="NS",
                   help="the robot's namespace (Srobot3, /Srobot3) or number (3, with "
                        "--name-prefix)")
    cli.add_shared(p, "--world",
                   help="world whose workstations to visit: a name under worlds/ or a "
                        ".world/.sdf path (default: %(default)s)")
    p.add_argument("--route", default="random", metavar="random|PATH.yaml",
                   help="'random': every workstation once per loop in a seeded random order; "
                        "or a route file (waypoints: names or {name, x, y, yaw}). The next stop "
                        "is skipped when it is the workstation the navigator has just taken "
                        "instead of the one sent (swap_range) (default: %(default)s)")
    p.add_argument("--loops", type=cli.non_negative_int, default=0, metavar="N",
                   help="loops over the route; 0 = forever (default: %(default)s)")
    cli.add_shared(p, "--seed",
                   help="seed of the random order, mixed with NS (default: %(default)s)")
    p.add_argument("--wait-timeout", type=cli.positive_float, default=30.0, metavar="SEC",
                   help="wall seconds to wait for the navigator (default: %(default)s)")
    p.add_argument("--service-time", type=cli.non_negative_float, default=None, metavar="SEC",
                   help="simulated seconds the robot stays at a workstation it reached before "
                   "its next goal takes effect (default: the world's service_time, else 0)")
    cli.add_shared(p, "--name-prefix",
                   help="prefix of robot namespaces, for a numeric NS (default: %(default)s)")
    p.add_argument("--coordinated", action="store_true",
                   help="ask the coordinator (swarm-coordinator) for every task instead of "
                   "following --route (swarm-up --coordination centralized)")
    p.add_argument("--faults", default=None, metavar="SPEC",
                   help="with --coordinated: the run's fault schedule (swarm-up's --faults), "
                   "whose kill-coordinator faults the commander waits out (default: none)")
    return p


def _namespace(ns: str, prefix: str) -> str:
    name = ns.strip()
    if name.isdigit():
        name = f"{prefix}{int(name)}"
    name = name[1:] if name.startswith("/") else name
    if not cli.is_ros_namespace(name):
        raise InputError(f"NS: {ns!r} is not a valid ROS namespace (ROS names: "
                         f"{cli.ROS_NAME_RULE}; separated by /)")
    return name


def _use_sim_time_by_default(node: BasicNavigator) -> None:
    """Turn ``use_sim_time`` on unless ``--ros-args`` (``-p`` or a params file) set it."""
    overrides = getattr(node, "_parameter_overrides", {})  # rclpy: the command line's values
    if "use_sim_time" not in overrides:
        node.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])


def _emit(line: str) -> None:
    print(line, flush=True)


def _non_ros_args(argv: list[str]) -> list[str]:
    """The command line without its ``--ros-args ... [--]`` part; InputError if that is bad."""
    try:
        return remove_ros_args([PROG, *argv])[1:]
    except RCLInvalidROSArgsError as exc:
        problem = str(exc).split(", at /")[0].removeprefix("Failed to parse ROS arguments: ")
        raise InputError(f"--ros-args: {problem}") from None


def _run(argv: list[str]) -> int:
    opts = _parser().parse_args(_non_ros_args(argv))
    ns = _namespace(opts.ns, opts.name_prefix)
    route = None if opts.coordinated else build_route(opts.world, opts.seed, ns, opts.route)
    service = (opts.service_time if opts.service_time is not None
               else world_service_time(opts.world))
    cfg = CommanderConfig(loops=opts.loops, wait_timeout=opts.wait_timeout,
                          service_time=service)

    runner = None
    code = EXIT_OK
    with node_session([PROG, *argv]) as nodes:
        executor = SingleThreadedExecutor()
        try:
            if opts.coordinated:
                _wait_for_coordinator(ns, executor, opts.wait_timeout)
            # A coordinated commander connects to its navigator once it reaches the coordinator.
            node = BasicNavigator(node_name=NODE_NAME, namespace=ns, connect=not opts.coordinated)
            nodes.append(node)
            _use_sim_time_by_default(node)
            node.get_logger().set_level(LoggingSeverity.WARN)  # the task lines say what happens
            if opts.coordinated:
                from swarm_commander.coordinated import CoordinatedRunner, coordinated_config

                runner = CoordinatedRunner(
                    node, coordinated_config(opts.faults, opts.wait_timeout), emit=_emit)
            else:
                runner = CommanderRunner(node, route, cfg, emit=_emit)
            executor.add_node(node)
            executor.spin_until_future_complete(runner.finished)
            code = runner.finished.result() if runner.finished.done() else EXIT_OK
        finally:  # then the session destroys the node; a Ctrl-C (also one that shut the
            # context down while a callback was publishing, rcl: "publisher's context is
            # invalid") ends quietly
            if runner is not None:
                if runner.started:  # first: stopping after a Ctrl-C may raise (context gone)
                    _emit(runner.summary())
                runner.stop()
            executor.shutdown(timeout_sec=0)
    if runner is not None and runner.error:
        print(f"{PROG}: error: {runner.error}", file=sys.stderr)
    return code


def main(args: list[str] | None = None) -> int:
    """Entry point of ``swarm-commander``.

    Args:
        args: the command line without the program name; ``sys.argv[1:]`` if None.

    Returns:
        0 when the route is done or on Ctrl-C; 2 on bad input or when no navigator answers;
        1 when a navigator answers but does not take goals.
    """
    argv = list(sys.argv[1:] if args is None else args)
    return run_cli(PROG, lambda: _run(argv))


if __name__ == "__main__":
    sys.exit(main())
