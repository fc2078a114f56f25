"""One ``/clock`` subscription for all the nodes of a process (:class:`SharedClock`).

Used by the group processes of ``swarm-up --processes K`` (:mod:`swarm_up.group`) and, to carry
the same traffic, by the messaging baseline's group processes (:mod:`swarm_bench.baseline_nodes`).
"""

from __future__ import annotations

import rclpy
import rclpy.parameter


class SharedClock:
    """One ``/clock`` subscription for all the nodes of this process.

    Every node with ``use_sim_time`` subscribes to ``/clock`` itself: with a navigator and a
    commander per robot, a group of 50 robots took 100 deliveries of every clock tick, each
    costing about as much as an odometry message (20 robots in 2 groups: RTF 3.16 with a
    subscription per node, 3.67 with one per process, the same simulated run).  Here one node
    (``<first ns>/clock``) subscribes and sets the simulated time of every adopted node's clock,
    as the node's own ``rclpy.time_source.TimeSource`` would (``TimeSource.attach_clock``); each
    node keeps its ``use_sim_time`` parameter, its ROS clock and its time.  The navigators go by
    the messages' stamps, not their clock; a commander's clock only stamps a goal when it has
    no status yet.  Relies on rclpy's ``Node._time_source`` and ``TimeSource._clock_sub`` (rclpy
    7.1.6); a node without them keeps its own subscription.

    Args:
        namespace: namespace of the clock node (the group's first robot's).
        context: the rclpy context (None: the default one).
    """

    def __init__(self, namespace: str, context=None):
        self.node = rclpy.create_node(
            "clock", namespace=namespace, context=context,
            parameter_overrides=[rclpy.parameter.Parameter(
                "use_sim_time", rclpy.parameter.Parameter.Type.BOOL, True)])
        """The node holding the subscription: the caller spins it."""
        self._source = getattr(self.node, "_time_source", None)

    def adopt(self, node) -> None:
        """Feed ``node``'s clock from the shared subscription and drop its own."""
        own = getattr(node, "_time_source", None)
        sub = getattr(own, "_clock_sub", None)
        if self._source is None or sub is None:
            return
        node.destroy_subscription(sub)
        own._clock_sub = None
        self._source.attach_clock(node.get_clock())

    def forget(self, node) -> None:
        """Stop feeding the clock of ``node`` (destroyed)."""
        if self._source is not None:
            self._source._associated_clocks.discard(node.get_clock())
