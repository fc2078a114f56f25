"""The ROS side of the live view: reads the fleet into a :class:`~swarm_viz.fleet_view.FleetState`
and publishes ``/swarm/markers``.

It runs in ``swarm-up``'s own process, in the metrics listener's context and thread
(:meth:`swarm_metrics.listener.MetricsListener.attach`): one DDS participant for both, and the
``nav_status`` stream the recorder already receives is handed over by a hook instead of a second
set of subscriptions.  Costs, per robot:

- ``/swarm/poses`` (:data:`swarm_common.topics.POSES`): every robot's pose in one message a tick,
  which the simulator publishes only while someone listens; best effort, depth 1.  Reading the
  ``N`` robots' ``odom`` instead made the simulator write, and this process wake up, ``N`` more
  times a tick;
- ``/<ns>/plan``, latched like the navigator's writer;
- ``/<ns>/scan`` only while a browser watches the robot (:meth:`FleetNode.watch`).

The poses and plans are subscribed to only while someone looks (:meth:`FleetNode.demand`): a
browser is connected, ``/swarm/markers`` has a subscriber, or ``/api/state`` was read, and for
:attr:`~swarm_viz.fleet_view.ViewConfig.idle_grace_s` after.  So ``--dashboard`` or ``--markers``
with nobody looking costs the swarm nothing: the simulator writes no ``/swarm/poses`` and the
navigators build no plan messages.  The plans are latched, so a new reader gets every robot's
current plan at once.

Every subscription is ``raw=True`` and read with :mod:`swarm_common.cdr` (rclpy's deserializer was
8 ms per plan).  The markers are built only while ``/swarm/markers`` has a
subscriber.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Iterable

import numpy as np
from geometry_msgs.msg import PoseArray
from nav_msgs.msg import Path
from rclpy.node import Node
from sensor_msgs.msg import LaserScan

from swarm_common import topics
from swarm_common.cdr import path_points, pose_array, scan_ranges
from swarm_common.nav_status import decode
from swarm_ros.qos import publisher, subscription
from swarm_viz.fleet_view import FleetState, ScanSample, ViewConfig, workstation_states


class FleetNode(Node):
    """Feeds a :class:`FleetState` from the swarm's topics; optionally publishes markers.

    Every method runs in the spin thread (callbacks, :meth:`on_status`, and :meth:`watch` via
    :meth:`swarm_metrics.listener.MetricsListener.call_soon`); ``lock`` guards ``fleet`` against
    the web server's thread.

    Args:
        fleet: the state to write.
        lock: taken around every write.
        workstations: :class:`swarm_scene.poi.Workstation` records.
        footprint: (K, 2) robot outline in base_footprint [m]; or a list of every robot's own
            (a mixed fleet).
        markers: publish ``/swarm/markers``.
        cfg: the view's settings.
        context: the rclpy context.
    """

    def __init__(self, fleet: FleetState, lock: threading.Lock, *, workstations=(),
                 footprint: np.ndarray | None = None, markers: bool = False,
                 cfg: ViewConfig | None = None, context=None):
        super().__init__("swarm_up_fleet", context=context)
        # state
        self.fleet = fleet
        self.lock = lock
        self.cfg = cfg = cfg or ViewConfig()
        self.workstations = tuple(workstations)
        self._ws_xy = np.array([w.pose[:2] for w in self.workstations]).reshape(-1, 2)
        self.footprint = (np.zeros((0, 2)) if footprint is None else
                          [np.asarray(f, dtype=float) for f in footprint]
                          if isinstance(footprint, list) else np.asarray(footprint, dtype=float))
        self.malformed = 0
        self.markers_published = 0
        self._scan_subs: dict[int, object] = {}
        self._goal_pubs: dict[str, object] = {}  # ns -> goal_pose publisher (live viewers')
        # the poses and plans, subscribed to while someone looks (demand)
        self._input_subs: list = []
        self._browsers = 0
        self._wanted_until = -np.inf  # time.monotonic() until which the inputs stay [s]
        self.input_activations = 0
        # publishers and timers
        self.markers_pub = None
        if markers:
            from visualization_msgs.msg import MarkerArray

            self.markers_pub = publisher(self, MarkerArray, topics.MARKERS)
        self.create_timer(1.0 / cfg.markers_hz, self._on_timer)

    # -- demand --------------------------------------------------------------------------------
    def demand(self, browsers: int | None = None) -> None:
        """Someone looks: ``browsers`` connected now (None: keep the count; a one-off read such as
        ``/api/state``).  Subscribes to the poses and plans if they are not yet (spin thread
        only, e.g. through :meth:`swarm_metrics.listener.MetricsListener.call_soon`)."""
        if browsers is not None:
            self._browsers = browsers
        self._wanted_until = time.monotonic() + self.cfg.idle_grace_s
        self._update_inputs()

    @property
    def inputs_active(self) -> bool:
        """Whether the poses and plans are subscribed to now."""
        return bool(self._input_subs)

    def _update_inputs(self) -> None:
        now = time.monotonic()
        if self._browsers > 0 or (self.markers_pub is not None
                                  and self.markers_pub.get_subscription_count() > 0):
            self._wanted_until = now + self.cfg.idle_grace_s
        if now < self._wanted_until and not self._input_subs:
            self.input_activations += 1
            self._input_subs.append(subscription(self, PoseArray, topics.POSES, self._on_poses,
                                                 qos=topics.POSES_READER_QOS, raw=True))
            for i, ns in enumerate(self.fleet.robots):
                self._input_subs.append(subscription(
                    self, Path, topics.PLAN, lambda buf, i=i: self._on_plan(i, buf), ns,
                    raw=True))
        elif now >= self._wanted_until and self._input_subs:
            for sub in self._input_subs:
                self.destroy_subscription(sub)
            self._input_subs.clear()

    # -- inputs --------------------------------------------------------------------------------
    def _on_poses(self, buf: bytes) -> None:
        try:
            stamp, poses = pose_array(buf)
        except ValueError:
            self.malformed += 1
            return
        with self.lock:
            for i, (x, y, yaw) in enumerate(poses[:len(self.fleet.robots)].tolist()):
                self.fleet.set_pose(i, stamp, x, y, yaw)

    def _on_plan(self, i: int, buf: bytes) -> None:
        try:
            path = path_points(buf)
        except ValueError:
            self.malformed += 1
            return
        with self.lock:
            self.fleet.set_path(i, path)

    def _on_scan(self, i: int, buf: bytes) -> None:
        try:
            stamp, a0, inc, rmin, rmax, ranges = scan_ranges(buf)
        except ValueError:
            self.malformed += 1
            return
        with self.lock:
            if i in self._scan_subs:
                pose = self.fleet.poses[i].copy()
                self.fleet.set_scan(i, ScanSample(stamp, pose, a0, inc, rmin, rmax, ranges))

    def on_status(self, ns: str, values: dict, message: str) -> None:
        """One ``nav_status`` (the metrics node's hook): its state, goal and values."""
        i = self.fleet.index.get(ns)
        if i is None:
            return
        record = decode(values, message)
        with self.lock:
            self.fleet.set_status(i, values, record.state, record.goal)

    def watch(self, indices: Iterable[int]) -> None:
        """Subscribe to the scans of exactly these robots (spin thread only)."""
        wanted = set(indices)
        for i in list(self._scan_subs):
            if i not in wanted:
                self.destroy_subscription(self._scan_subs.pop(i))
                with self.lock:
                    self.fleet.drop_scan(i)
        for i in sorted(wanted - self._scan_subs.keys()):
            ns = self.fleet.robots[i]
            self._scan_subs[i] = subscription(
                self, LaserScan, topics.SCAN, lambda buf, i=i: self._on_scan(i, buf), ns,
                raw=True)

    @property
    def watched(self) -> frozenset[int]:
        """The robots whose scans are subscribed to."""
        return frozenset(self._scan_subs)

    def publish_goal(self, ns: str, x: float, y: float, yaw: float, frame: str = "map") -> None:
        """Publish a goal on ``/<ns>/goal_pose`` (a live viewer's; spin thread only): the
        navigator drives there, stamped with the latest simulated time it knows."""
        from geometry_msgs.msg import PoseStamped

        pub = self._goal_pubs.get(ns)
        if pub is None:
            pub = self._goal_pubs[ns] = publisher(self, PoseStamped, topics.GOAL_POSE, ns)
        msg = PoseStamped()
        msg.header.frame_id = frame
        with self.lock:
            t_ns = int(self.fleet.pose_stamp_ns.max()) if len(self.fleet.robots) else 0
        msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(t_ns, 1_000_000_000)
        msg.pose.position.x, msg.pose.position.y = float(x), float(y)
        msg.pose.orientation.z, msg.pose.orientation.w = math.sin(yaw / 2), math.cos(yaw / 2)
        pub.publish(msg)

    # -- outputs -------------------------------------------------------------------------------
    def workstation_states(self) -> tuple[list[str], list[int]]:
        """:func:`swarm_viz.fleet_view.workstation_states` now (the caller holds ``lock``)."""
        f = self.fleet
        return workstation_states(self._ws_xy, f.poses[:, :2], f.states, f.goals, self.cfg)

    def _on_timer(self) -> None:
        self._update_inputs()
        if self.markers_pub is None or self.markers_pub.get_subscription_count() == 0:
            return
        from swarm_viz.markers import fleet_markers

        stamp = self.get_clock().now().to_msg()
        with self.lock:
            ws_states, _ = self.workstation_states()
            msg = fleet_markers(self.fleet, self.footprint, self.workstations, ws_states, stamp)
        self.markers_pub.publish(msg)
        self.markers_published += 1
