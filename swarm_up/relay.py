"""One copy of the robots' states per host: a rank's relay of ``/swarm/robot_states``.

The simulator writes every robot's state once a tick (:data:`swarm_common.topics.ROBOT_STATES`)
and every group process renders its robots' sensors from it (:mod:`swarm_up.feed`). Over
UDP, DDS sends a message once to every reader process, so a host of K group processes would
take K copies of it from rank 0 each tick. On a rank other than 0 with more than one group
process, ``swarm-up`` reads it once and writes it again, byte for byte, on the rank's own topic
(:func:`swarm_common.topics.rank_robot_states`), which only that host's group processes read:
one copy crosses the network per host and tick (docs/guides/multi_host.md). The messages are
the simulator's, in its order; the lockstep holds at most one tick's states in flight, so the
reliable topics on both sides lose none.
"""

from __future__ import annotations

import threading


class StatesRelay:
    """A node ``/swarm/rank<R>/states_relay``, spun by an executor and a thread of its own, that
    republishes every ``/swarm/robot_states`` message on ``/swarm/rank<R>/robot_states`` as it
    arrives (its CDR bytes, not decoded).

    It lives in the context (the DDS participant) of ``swarm-up``'s link between the hosts
    (:class:`swarm_up.hosts.HostLink`): in a second participant of the same process, Fast DDS
    2.14.5 deadlocked once when the link destroyed a writer (its discovery delivered in-process
    to the other participant, ``PDP::removeWriterProxyData`` waiting on a mutex), and the rank
    never ended.

    Args:
        rank: this host's rank (> 0).
        context: the ``rclpy`` context to make the node in (initialised; the caller shuts it
            down after :meth:`close`).

    Attributes:
        relayed: how many messages it has republished.
    """

    def __init__(self, rank: int, context):
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.node import Node
        from sensor_msgs.msg import PointCloud2

        from swarm_common import topics
        from swarm_ros.qos import publisher, subscription

        self.relayed = 0
        self._context = context
        self._node = Node("states_relay", namespace=f"/swarm/rank{rank}", context=self._context)
        self._executor = SingleThreadedExecutor(context=self._context)
        self._executor.add_node(self._node)
        out = topics.rank_robot_states(rank)
        self.topic = out.name
        """The rank's topic it writes."""
        self._pub = publisher(self._node, PointCloud2, out)
        subscription(self._node, PointCloud2, topics.ROBOT_STATES, self._on_states, raw=True)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._spin, name="states_relay", daemon=True)
        self._thread.start()

    def _on_states(self, buf: bytes) -> None:
        self._pub.publish(buf)
        self.relayed += 1

    def _spin(self) -> None:
        # A spin_once loop on a SingleThreadedExecutor: the thread publishes, which rclpy
        # 7.1.6's EventsExecutor does not bear (docs/ARCHITECTURE.md, "Executors").
        while not self._stop.is_set() and self._context.ok():
            self._executor.spin_once(timeout_sec=0.05)

    def close(self) -> None:
        """Stop the thread and destroy the node (idempotent); the context stays the caller's."""
        self._stop.set()
        self._thread.join(timeout=2.0)
        if self._node is not None:
            self._executor.shutdown(timeout_sec=0)
            self._node.destroy_node()
            self._node = None
