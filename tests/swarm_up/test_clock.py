"""One /clock subscription per group process (swarm_up.clock.SharedClock)."""

import pytest
import rclpy
import rclpy.parameter
from builtin_interfaces.msg import Time
from rclpy.qos import QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from swarm_up.clock import SharedClock
from tests.support.ros import ros_context, spin_until

SIM_TIME = [rclpy.parameter.Parameter("use_sim_time", rclpy.parameter.Parameter.Type.BOOL, True)]


def _clock_subscriptions(node) -> int:
    return sum(1 for info in node.get_subscriptions_info_by_topic("/clock")
               if info.node_namespace.startswith("/shared_clock_test"))


@pytest.mark.node
def test_adopted_nodes_follow_one_clock_subscription():
    with ros_context() as (ctx, executor):
        nodes = [rclpy.create_node(f"n{i}", namespace="/shared_clock_test", context=ctx,
                                   parameter_overrides=SIM_TIME) for i in range(3)]
        clock = SharedClock("/shared_clock_test", context=ctx)
        pub_node = rclpy.create_node("sim", context=ctx)
        pub = pub_node.create_publisher(
            Clock, "/clock", QoSProfile(depth=1, reliability=ReliabilityPolicy.BEST_EFFORT))
        for node in (*nodes, clock.node, pub_node):
            executor.add_node(node)
        spin_until(executor, lambda: _clock_subscriptions(pub_node) == 4, 10.0,
                   "the nodes' own /clock subscriptions")
        for node in nodes:
            clock.adopt(node)
            clock.adopt(node)  # a second adoption changes nothing
        spin_until(executor, lambda: _clock_subscriptions(pub_node) == 1, 10.0,
                   "one /clock subscription left")

        def all_at(sec: int, which) -> bool:
            pub.publish(Clock(clock=Time(sec=sec, nanosec=5)))
            return all(n.get_clock().now().nanoseconds == sec * 10**9 + 5 for n in which)

        spin_until(executor, lambda: all_at(42, nodes), 10.0, "every node at t = 42 s")
        assert all(n.get_parameter("use_sim_time").value for n in nodes)
        clock.forget(nodes[0])  # destroyed nodes are no longer fed
        spin_until(executor, lambda: all_at(43, nodes[1:]), 10.0, "t = 43 s")
        assert nodes[0].get_clock().now().nanoseconds == 42 * 10**9 + 5
        for node in (*nodes, clock.node, pub_node):
            node.destroy_node()
