"""The test helpers' own contract: a ``ros_context`` leaves no endpoint behind in the domain."""

import time

import pytest
import rclpy
from rclpy.qos import QoSProfile
from std_msgs.msg import String

from tests.support.ros import ros_context

pytestmark = pytest.mark.node

TOPIC = "/support_ros_test/leftover"


def test_a_closed_ros_context_leaves_no_subscriber_behind():
    """The nodes are destroyed on exit even while the test still holds them (CI stop 33: a
    shut-down context's live nodes kept a ``/swarm/markers`` subscriber in the domain)."""
    with ros_context() as (ctx, executor):
        # held by this frame until the test returns, past its context's end
        held = rclpy.create_node("leftover_reader", context=ctx)
        held.create_subscription(String, TOPIC, lambda _msg: None, QoSProfile(depth=1))
        executor.add_node(held)
    with ros_context() as (ctx, executor):
        node = rclpy.create_node("leftover_probe", context=ctx)
        pub = node.create_publisher(String, TOPIC, QoSProfile(depth=1))
        executor.add_node(node)
        # a reader that is still there is discovered within a fraction of this time
        end = time.monotonic() + 3.0
        while time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
            assert pub.get_subscription_count() == 0
