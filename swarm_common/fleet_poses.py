"""``/swarm/poses``: the whole fleet's ground-truth poses in one message a tick.

The simulator publishes it, only while someone subscribes, as a ``geometry_msgs/PoseArray`` in
``map``: ``poses[i]`` is robot ``i`` (0-based) of the simulator's namespaces, ``/<prefix>1`` ...
``/<prefix>N`` in that order; ``header.stamp`` is the tick's simulated time.  A whole-fleet
view (the dashboard) reads this one message instead of ``N`` odometry topics: one write and one
wake-up a tick instead of ``N`` (at 100 robots that was most of what the dashboard cost the
simulation, docs/ARCHITECTURE.md, Dashboard).

The writer is reliable with depth 1 (a reliable writer serves best-effort readers too, without
acknowledgements); a live view reads it best effort.
"""

from __future__ import annotations

from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy

POSES_TOPIC = "/swarm/poses"
POSES_WRITER_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                              reliability=ReliabilityPolicy.RELIABLE)
POSES_READER_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                              reliability=ReliabilityPolicy.BEST_EFFORT)
