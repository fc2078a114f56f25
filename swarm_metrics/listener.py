"""The orchestrator's metrics node: listens to the swarm and feeds a :class:`RunRecorder`.

It subscribes to ``/<ns>/nav_status`` of every robot, ``/swarm/events`` and ``/clock`` (names,
types and QoS: :mod:`swarm_common.topics`), converts each message to plain values and hands
them to the pure recorder (``swarm_metrics.aggregate``). For the communication load it also
takes, serialized (``raw``: only their size and sender are read), the coordinator's topics
(:mod:`swarm_common.coordination`) and the latched ``/map``.  It spins in a background thread
with its own executor and context, so the orchestrator's main thread keeps supervising.

The executor is rclpy's ``EventsExecutor``, looped on ``spin_once`` as the group processes do
(``docs/ARCHITECTURE.md``, Executors).  ``SingleThreadedExecutor`` rebuilds its wait set in Python
on every ``spin_once`` from every subscription and its QoS event handlers: with 100 robots'
``nav_status`` that cost about half a core in the orchestrator (shared/reference/profile_100.md).
The node only subscribes, so the known deadlock of these wheels (publishing from another thread
while the EventsExecutor spins) cannot arise.
"""

from __future__ import annotations

import json
import queue
import threading
import time
from collections.abc import Callable

import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from nav_msgs.msg import OccupancyGrid
from rclpy.experimental import EventsExecutor
from rclpy.node import Node
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
from std_msgs.msg import String

from swarm_common import cdr, topics
from swarm_common.coordination import (
    METRICS_NODE,
    ContractError,
    decode_state,
)
from swarm_metrics.aggregate import RunRecorder
from swarm_ros.qos import subscription

TEARDOWN_S = 15.0  # [s] wall: how long stop() waits for the nodes' teardown


def _text(raw: bytes) -> str:
    """The text of a serialized ``std_msgs/String`` (:func:`swarm_common.cdr.string_data`);
    ``""`` if malformed."""
    try:
        return cdr.string_data(raw)
    except ValueError:
        return ""


class MetricsNode(Node):
    """Converts the swarm's status, events and clock into recorder calls.

    Args:
        recorder: the recorder to feed (guarded by ``lock``).
        lock: taken around every recorder call.
        t0: ``time.monotonic()`` of the run's start [s]; statuses are stamped relative to it.
        context: the rclpy context to create the node in.
    """

    def __init__(self, recorder: RunRecorder, lock: threading.Lock, t0: float, context=None,
                 status_hooks: tuple[Callable[[str, dict, str], None], ...] = ()):
        super().__init__(METRICS_NODE, context=context)
        # state
        self._recorder = recorder
        self._lock = lock
        self._t0 = t0
        self._status_hooks = status_hooks
        # subscriptions
        self._subs = [
            subscription(self, DiagnosticStatus, topics.NAV_STATUS,
                         lambda msg, ns=ns: self._on_nav_status(ns, msg), ns,
                         topics.NAV_STATUS_METRICS_READER_QOS)
            for ns in recorder.robots
        ]
        self._subs += [
            subscription(self, DiagnosticArray, topics.EVENTS, self._on_events),
            subscription(self, Clock, topics.CLOCK, self._on_clock,
                         qos=topics.CLOCK_METRICS_READER_QOS),
            # communication load: the coordinator's topics and the map, serialized
            subscription(self, String, topics.COORDINATOR_REQUEST, self._on_request,
                         qos=topics.COMM_METRICS_READER_QOS, raw=True),
        ]
        self._subs += [
            subscription(self, String, topics.ASSIGNMENT,
                         lambda raw, ns=ns: self._on_comm("assignment", ns, raw), ns,
                         topics.COMM_METRICS_READER_QOS, raw=True)
            for ns in recorder.robots
        ]
        self._subs += [
            subscription(self, String, topics.COORDINATOR_STATE, self._on_state, raw=True),
            subscription(self, OccupancyGrid, topics.MAP, self._on_map, raw=True),
        ]

    def _on_nav_status(self, ns: str, msg: DiagnosticStatus) -> None:
        values = {kv.key: kv.value for kv in msg.values}
        wall_s = time.monotonic() - self._t0
        with self._lock:
            self._recorder.on_status(ns, values, wall_s, message=msg.message)
        for hook in self._status_hooks:
            hook(ns, values, msg.message)

    def _on_events(self, msg: DiagnosticArray) -> None:
        with self._lock:
            for status in msg.status:
                self._recorder.on_event(status.name, {kv.key: kv.value for kv in status.values})

    def _on_request(self, raw: bytes) -> None:
        text = _text(raw)
        try:
            robot = str(json.loads(text).get("robot", ""))
        except (ValueError, AttributeError):
            robot = ""
        if robot:
            with self._lock:
                self._recorder.on_comm("request", robot.strip("/"), len(raw), key=text)

    def _on_comm(self, topic: str, robot: str, raw: bytes) -> None:
        key = _text(raw) if topic == "assignment" else None
        with self._lock:
            self._recorder.on_comm(topic, robot, len(raw), key=key)

    def _on_state(self, raw: bytes) -> None:
        self._on_comm("state", "", raw)
        try:
            epoch = decode_state(_text(raw))
        except ContractError:
            return  # counted as communication; the coordinator's "up" event counts the start
        with self._lock:
            self._recorder.on_coordinator_up(epoch)

    def _on_map(self, raw: bytes) -> None:
        with self._lock:
            self._recorder.map_bytes = len(raw)

    def _on_clock(self, msg: Clock) -> None:
        sim_s = msg.clock.sec + msg.clock.nanosec * 1e-9
        with self._lock:
            self._recorder.on_clock(sim_s)


class MetricsListener:
    """Runs a :class:`MetricsNode` in a background thread with its own context and executor.

    Other nodes may share its context and thread (one DDS participant, no second discovery):
    :meth:`attach` them before :meth:`start`, and :meth:`call_soon` runs a function in the spin
    thread, the only thread that may touch them (``docs/ARCHITECTURE.md``, Executors).

    Args:
        robots: the namespaces, without ``/``.
        t0: ``time.monotonic()`` of the run's start [s].
    """

    def __init__(self, robots: tuple[str, ...], t0: float):
        self.recorder = RunRecorder(robots=tuple(robots))
        self.lock = threading.Lock()
        self._t0 = t0
        self._context = rclpy.Context()
        self._node: MetricsNode | None = None
        self._executor: EventsExecutor | None = None
        self._thread: threading.Thread | None = None
        self._running = threading.Event()
        self._factories: list[Callable] = []
        self._status_hooks: list[Callable[[str, dict, str], None]] = []
        self._extra_nodes: list[Node] = []
        self._calls: queue.SimpleQueue[Callable[[], None]] = queue.SimpleQueue()
        self.stuck = False
        """The last :meth:`stop` did not finish its teardown in time."""

    def attach(self, factory: Callable[[rclpy.Context], Node],
               on_status: Callable[[str, dict, str], None] | None = None) -> None:
        """Spin another node with this one (call before :meth:`start`).

        Args:
            factory: builds the node in the given context (called by :meth:`start`).
            on_status: called in the spin thread with ``(ns, values, message)`` of every
                ``nav_status`` (after the recorder has it), so the node needs no subscription
                of its own.
        """
        self._factories.append(factory)
        if on_status is not None:
            self._status_hooks.append(on_status)

    def call_soon(self, fn: Callable[[], None]) -> None:
        """Run ``fn()`` in the spin thread, between two callbacks (thread-safe)."""
        self._calls.put(fn)

    def start(self) -> None:
        """Create the node (and the attached ones) and start spinning them."""
        rclpy.init(context=self._context, signal_handler_options=SignalHandlerOptions.NO)
        self._node = MetricsNode(self.recorder, self.lock, self._t0, context=self._context,
                                 status_hooks=tuple(self._status_hooks))
        self._executor = EventsExecutor(context=self._context)
        self._executor.add_node(self._node)
        for factory in self._factories:
            node = factory(self._context)
            self._extra_nodes.append(node)
            self._executor.add_node(node)
        self._running.set()
        self._thread = threading.Thread(target=self._spin, name="swarm_up_metrics", daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while self._running.is_set() and self._context.ok():
            try:
                while not self._calls.empty():
                    self._calls.get_nowait()()
                self._executor.spin_once(timeout_sec=0.1)
            except Exception:  # a shutdown race must not kill the thread loudly
                if not self._running.is_set():
                    break
                raise

    def stop(self) -> bool:
        """Stop spinning, destroy the nodes and shut their context down (idempotent).

        The nodes are destroyed in a thread of their own, waited for at most
        :data:`TEARDOWN_S` wall seconds: Fast DDS 2.14 can deadlock while it removes a local
        writer and the participant takes in the departure of many others at once (the
        children just stopped; seen once on a 2-core machine under a stress test).  Nothing
        simulated depends on the teardown: the recorder's figures are complete by then.

        Returns:
            False if the teardown did not finish in time (:attr:`stuck`; the process should
            then end without finalizing the middleware, see :func:`swarm_up.orchestrator.run`).
        """
        self._running.clear()
        if self._thread is not None:
            self._thread.join(timeout=2.0)
            self._thread = None
        nodes = [*self._extra_nodes, *([self._node] if self._node is not None else [])]
        executor, self._executor, self._node = self._executor, None, None
        self._extra_nodes = []
        done = threading.Event()

        def teardown() -> None:
            if executor is not None:
                executor.shutdown(timeout_sec=1.0)
            for node in nodes:
                node.destroy_node()
            if self._context.ok():
                self._context.try_shutdown()
            done.set()

        threading.Thread(target=teardown, name="swarm_up_metrics_teardown", daemon=True).start()
        self.stuck = not done.wait(TEARDOWN_S)
        return not self.stuck

    def snapshot(self) -> tuple[int, int]:
        """``(spawned, ready)`` robot counts now."""
        with self.lock:
            return self.recorder.spawned_count, self.recorder.ready_count
