"""``/swarm/poses``: the whole fleet's ground-truth poses in one message a tick.

The simulator publishes it, only while someone subscribes, as a ``geometry_msgs/PoseArray`` in
``map``: ``poses[i]`` is robot ``i`` (0-based) of the simulator's namespaces, ``/<prefix>1`` ...
``/<prefix>N`` in that order; ``header.stamp`` is the tick's simulated time.  A whole-fleet
view (the dashboard) reads this one message instead of ``N`` odometry topics: one write and one
wake-up a tick instead of ``N`` (docs/ARCHITECTURE.md, "The live view").

QoS: the writer is reliable, keep last :data:`POSES_DEPTH` (a reliable writer serves
best-effort readers too, without acknowledgements); a live view reads it best effort with the
same depth.  Pure: no ROS import (the nodes build their ``QoSProfile`` from these).
"""

from __future__ import annotations

POSES_TOPIC = "/swarm/poses"
POSES_DEPTH = 1
