"""A simulated robot's sensor topics: ``odom``, ``ground_truth`` and ``scan`` under its namespace.

Written as CDR bytes (:mod:`swarm_common.cdr`): 100 robots' messages a tick, each a
``struct.pack`` instead of rclpy's conversion.  Used by the simulator
(:class:`swarm_sim.node.SimulatorNode`) and the messaging baseline's simulator
(:class:`swarm_bench.baseline_nodes.BaselineSimNode`), so both publish the same messages in the
same order.
"""

from __future__ import annotations

import math
from collections.abc import Collection, Sequence

import numpy as np
from nav_msgs.msg import Odometry
from sensor_msgs.msg import LaserScan

from swarm_common import topics
from swarm_common.cdr import LaserScanWriter, OdometryWriter
from swarm_ros.qos import publisher


class RobotTopics:
    """One robot's ``odom`` (frame ``<ns>/odom``), ``ground_truth`` (frame ``map``) and
    ``scan`` publishers, with QoS of :mod:`swarm_common.topics`.

    Args:
        node: the publishing node.
        ns: the robot's namespace, without the leading slash.
        scan: the writer of its scans (its lidar's frame, beams and rate).
    """

    def __init__(self, node, ns: str, scan: LaserScanWriter):
        self.odom_pub = publisher(node, Odometry, topics.ODOM, ns)
        self.truth_pub = publisher(node, Odometry, topics.GROUND_TRUTH, ns)
        self.scan_pub = publisher(node, LaserScan, topics.SCAN, ns)
        self._odom = OdometryWriter(f"{ns}/odom", f"{ns}/base_footprint")
        self._truth = OdometryWriter("map", f"{ns}/base_footprint")
        self._scan = scan

    def publish_scan(self, t_ns: int, ranges: np.ndarray) -> None:
        """The scan of tick ``t_ns`` [ns]: (M,) ranges [m]."""
        self.scan_pub.publish(self._scan.write(t_ns, ranges))

    def publish_odom(self, t_ns: int, pose: Sequence[float], v: float, w: float,
                     odom: bool = True, truth: bool = True) -> None:
        """The odometry of tick ``t_ns`` [ns] and, while someone listens, the ground truth.

        Args:
            t_ns: [ns] the stamp.
            pose: x [m], y [m], yaw [rad] in ``map`` (odometry is exact: ``odom`` = ``map``).
            v: [m/s] linear velocity in the robot's frame.
            w: [rad/s] angular velocity.
            odom: publish the odometry (False: a fault mutes it; the ground truth still flows).
            truth: publish the ground truth (False: a tick's odometry sent again to a
                navigator that may have lost it; the ground truth was sent once).

        The ground truth goes out only while it has a subscriber (a probe, a recorder, ``ros2
        topic echo``): in a swarm-up run nothing reads it, and converting and writing 100
        messages a tick for no reader was a third of the simulator's publishing time.
        """
        x, y, yaw = pose
        qz, qw = math.sin(yaw / 2.0), math.cos(yaw / 2.0)
        if odom:
            self.odom_pub.publish(self._odom.write(t_ns, x, y, qz, qw, v, w))
        if truth and self.truth_pub.get_subscription_count():
            self.truth_pub.publish(self._truth.write(t_ns, x, y, qz, qw, v, w))


def publish_sensors(robots: Sequence[RobotTopics], t_ns: int, poses: np.ndarray,
                    v: np.ndarray, w: np.ndarray, scans: Sequence | None,
                    mute_odom: Collection[int] = (), mute_scan: Collection[int] = (),
                    lazy: bool = False) -> None:
    """Every robot's sensor messages of tick ``t_ns`` [ns], robot after robot, its scan then its
    odometry: a navigator answers once it has both, so the first robots' navigators start while
    the last robots' messages are still being written (all scans first held every navigator back
    by the 100 scans' writing time).

    Args:
        robots: (N) the robots' topics.
        t_ns: [ns] the stamp.
        poses: (N, 3) x, y, yaw in ``map`` [m, m, rad].
        v: (N,) [m/s]; w: (N,) [rad/s].
        scans: (N) ranges per robot (None: that robot's lidar does not scan this tick), or None
            when no lidar scans this tick.
        mute_odom: robots whose odometry (and ground truth) is not published (faults).
        mute_scan: robots whose scan is not published (faults).
        lazy: write a robot's ``odom`` and ``scan`` only while that topic has a reader (the
            group processes' navigators read them from ``/swarm/robot_states`` instead); a
            reader that joins gets them from the next tick on.
    """
    pose_rows = poses.tolist()
    for i, robot in enumerate(robots):
        if (scans is not None and i not in mute_scan and scans[i] is not None
                and not (lazy and not robot.scan_pub.get_subscription_count())):
            robot.publish_scan(t_ns, scans[i])
        robot.publish_odom(t_ns, pose_rows[i], float(v[i]), float(w[i]), i not in mute_odom
                           and not (lazy and not robot.odom_pub.get_subscription_count()))
