"""A group process's robots' odometry and scans, made in the process from the robots' states.

Each control tick the simulator publishes every robot's state in one message
(:data:`swarm_common.topics.ROBOT_STATES`).  A :class:`SensorFeed` renders its own robots' scans
from it with the simulator's sensor code (:class:`swarm_sim.sensors.SwarmSensors`: the same
world, fleet and seed, so the same ranges and noise to the last bit) and hands each navigator the
odometry and the scan it would have read from ``odom`` and ``scan``
(:func:`swarm_common.cdr.odom_reading`, :func:`swarm_common.cdr.scan_reading`): the navigators
see the same inputs, and the simulator writes a robot's ``odom`` and ``scan`` only while
someone else reads them (step 1 of docs/design/scaling.md).  The lockstep is unchanged: the
simulator still waits for every robot's answer, and sends the states again when one is late.

Used by :mod:`swarm_up.group` and, with fixed ranges, by the messaging baseline's group
processes (:mod:`swarm_bench.baseline_nodes`).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence

import numpy as np
from sensor_msgs.msg import PointCloud2

from swarm_common import topics
from swarm_common.cdr import ODOM_PUBLISHED, SCAN_PUBLISHED, odom_reading, robot_states
from swarm_ros.qos import subscription


class SensorFeed:
    """Feeds the navigators of a group process from ``/swarm/robot_states``.

    Args:
        node: the node that subscribes (the group's clock node).
        navigators: namespace -> the navigator now running for it (``take_scan``,
            ``take_odom``); read at every tick, so a restarted navigator is fed and a killed one
            is not.
        names: (N) every robot's namespace, in the simulator's index order.
        sensors: the renderer: ``due_mask(ticks)`` -> (N,) bool, ``scans(poses, ticks, rows)``
            (:meth:`swarm_sim.sensors.SwarmSensors.scans`) and ``skip(ticks)``.
        scan_meta: (N) each robot's scan geometry as a navigator reads it
            (:func:`swarm_common.cdr.scan_reading`).
        period_ns: [ns] one control tick.
        busy: called when a message came in (the group's batch of answers,
            :meth:`swarm_up.answers.AnswerBatch.busy`), or None.
        warn: a line for a malformed message (throttled by the caller), or None.
        topic: where the states come from: :data:`~swarm_common.topics.ROBOT_STATES` (the
            simulator's), or a rank's relay of it
            (:func:`~swarm_common.topics.rank_robot_states`).
    """

    def __init__(self, node, navigators: Mapping, names: Sequence[str], sensors,
                 scan_meta: Sequence[tuple], period_ns: int,
                 busy: Callable[[], None] | None = None,
                 warn: Callable[[str], None] | None = None,
                 topic: topics.Topic = topics.ROBOT_STATES):
        self.navigators = navigators
        self.names = list(names)
        self.sensors = sensors
        self.scan_meta = list(scan_meta)
        self.period_ns = int(period_ns)
        self.busy = busy
        self.warn = warn
        index = {ns: i for i, ns in enumerate(self.names)}
        self.mine = sorted(index[ns] for ns in navigators if ns in index)
        """The indices of this process's robots, ascending."""
        self.t_ns = -1  # the latest tick fed
        self.next_tick = 1  # the first tick whose noise is not drawn yet (tick 0 is never cast)
        self._scans: dict[int, np.ndarray] = {}
        self._states = None
        self._warned = -1e9
        self.topic = topic
        self.sub = subscription(node, PointCloud2, topic, self.on_states, raw=True)

    def on_states(self, buf: bytes) -> None:
        """A tick's states: render this tick's scans once, then feed every navigator of the
        process (again, when the simulator sends a tick again)."""
        if self.busy is not None:
            self.busy()
        try:
            t, states = robot_states(buf)
        except ValueError as exc:
            self._say(f"{self.topic.name}: dropped a malformed message ({exc})")
            return
        if len(states) != len(self.names):
            self._say(f"{self.topic.name}: {len(states)} robots, not "
                      f"{len(self.names)}: dropped")
            return
        if t < self.t_ns:
            return  # an older tick sent again: answered already
        if t > self.t_ns:
            self._render(t, states)
        self._feed(t)

    def _render(self, t: int, states: np.ndarray) -> None:
        ticks = round(t / self.period_ns)
        for k in range(self.next_tick, ticks):  # ticks not seen (a late start): their noise
            self.sensors.skip(k)
        self.next_tick = ticks + 1
        self._scans = {}
        due = self.sensors.due_mask(ticks)
        if due.any():
            rows = [i for i in self.mine if due[i]]
            if rows:
                poses = np.column_stack((states["x"], states["y"], states["yaw"]))
                self._scans = dict(zip(rows, self.sensors.scans(poses, ticks, rows),
                                       strict=True))
            else:
                self.sensors.skip(ticks)
        self.t_ns = t
        self._states = states

    def _feed(self, t: int) -> None:
        states, scans = self._states, self._scans
        published = states["published"]
        rows = states[["x", "y", "yaw", "v", "w"]]
        for i in self.mine:
            nav = self.navigators.get(self.names[i])
            if nav is None:
                continue  # killed by a fault; its successor is fed once it runs
            ranges = scans.get(i)
            if ranges is not None and published[i] & SCAN_PUBLISHED:
                nav.take_scan(t, self.scan_meta[i], ranges)
            if published[i] & ODOM_PUBLISHED:
                x, y, yaw, v, w = rows[i].tolist()
                nav.take_odom(odom_reading(t, x, y, yaw, v, w))

    def _say(self, text: str) -> None:
        now = time.monotonic()
        if self.warn is not None and now - self._warned >= 5.0:
            self._warned = now
            self.warn(text)
