"""A navigator's ROS interface, written once: what :class:`swarm_nav.node.NavigatorNode` and the
benchmark's mirror navigator (:class:`swarm_bench.baseline_nodes.BaselineNavigatorNode`) publish,
subscribe to and serve, with the names and QoS of :mod:`swarm_common.topics`."""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

from diagnostic_msgs.msg import DiagnosticStatus
from geometry_msgs.msg import PoseStamped, TwistStamped
from nav_msgs.msg import OccupancyGrid, Odometry, Path
from sensor_msgs.msg import LaserScan
from std_srvs.srv import Trigger

from swarm_common import topics
from swarm_ros.qos import publisher, subscription


class NavigatorEndpoints(NamedTuple):
    """The navigator's publishers (``cmd_vel`` and ``plan`` are written as CDR bytes) and its
    ``goal_pose`` subscription (its ``get_publisher_count()``, the writers matched to it, says
    whether a commander is connected: per entity, where ``Node.count_publishers`` walks the
    whole graph, 20,000 endpoints at 1,000 robots)."""

    cmd_vel: object
    plan: object
    nav_status: object
    goal_pose: object


def navigator_interface(node, on_map: Callable, on_scan: Callable | None,
                        on_odom: Callable | None, on_goal_pose: Callable, on_cancel: Callable,
                        on_goal_coming: Callable) -> NavigatorEndpoints:
    """Create a navigator's publishers, subscriptions and service on ``node`` (its namespace is
    the robot's).

    ``scan`` and ``odom`` come every tick and are read raw (``on_scan(bytes)``,
    ``on_odom(bytes)``, decoded with :mod:`swarm_common.cdr`: rclpy built 15 message objects per
    odometry message, 10 % of a group process's CPU); ``/map`` and ``goal_pose`` as messages;
    ``on_cancel`` serves ``navigator/cancel`` and ``on_goal_coming`` ``navigator/goal_coming``
    (both ``std_srvs/Trigger``).  ``on_scan`` or ``on_odom`` None: no subscription (a group
    process feeds its navigators those, :mod:`swarm_up.feed`).

    Returns:
        The publishers of ``cmd_vel``, ``plan`` and ``nav_status``, and the ``goal_pose``
        subscription.
    """
    cmd_vel = publisher(node, TwistStamped, topics.CMD_VEL)
    plan = publisher(node, Path, topics.PLAN)
    nav_status = publisher(node, DiagnosticStatus, topics.NAV_STATUS)
    subscription(node, OccupancyGrid, topics.MAP, on_map)
    if on_scan is not None:
        subscription(node, LaserScan, topics.SCAN, on_scan, raw=True)
    if on_odom is not None:
        subscription(node, Odometry, topics.ODOM, on_odom, raw=True)
    goal_pose = subscription(node, PoseStamped, topics.GOAL_POSE, on_goal_pose)
    node.create_service(Trigger, topics.CANCEL_SERVICE, on_cancel)
    node.create_service(Trigger, topics.GOAL_COMING_SERVICE, on_goal_coming)
    return NavigatorEndpoints(cmd_vel, plan, nav_status, goal_pose)
