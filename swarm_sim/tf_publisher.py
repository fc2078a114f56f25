"""The swarm's live ``/tf``, ``/tf_static`` and every robot's ``robot_description``.

What ``robot_state_publisher`` and a simulator's odometry broadcaster give a nav2 robot, for
the whole swarm, from the simulator node (``tf2_msgs`` is built here:
:mod:`swarm_ros.built_interfaces`):

- ``/tf_static`` (:data:`swarm_common.topics.TF_STATIC`), once: for every robot ``map`` ->
  ``<ns>/odom`` (identity: the simulated odometry is exact) and its URDF's joints, prefixed with
  its namespace (``<ns>/base_footprint`` -> ``<ns>/base_link`` -> ``<ns>/base_scan``...);
- ``/tf`` (:data:`swarm_common.topics.TF`), every tick while it has a reader: every robot's
  ``<ns>/odom`` -> ``<ns>/base_footprint``, one message, stamped with simulated time;
- ``/<ns>/robot_description`` (:data:`swarm_common.topics.ROBOT_DESCRIPTION`), once, latched: the
  URDF with its own link names; RViz2's RobotModel display takes it with TF Prefix ``<ns>``.

One global tree (prefixed frames on ``/tf``), not nav2's multi-robot layout (``/<ns>/tf`` with
plain frame names): the simulator's odometry and scans already name prefixed frames
(``<ns>/odom``, ``<ns>/base_scan``), and one RViz2 shows the swarm.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from swarm_common import topics
from swarm_common.cdr import TFMessageWriter
from swarm_ros.qos import publisher
from swarm_scene.robot_frames import FOOTPRINT, RobotFrames


def static_transforms(namespaces: Sequence[str], frames: Sequence[RobotFrames]):
    """The ``/tf_static`` message of the swarm (:mod:`swarm_sim.tf_publisher`'s docstring).

    Args:
        namespaces: (N) the robots' namespaces, without the leading slash.
        frames: (N) each robot's model frames.

    Returns:
        A ``tf2_msgs/msg/TFMessage``, stamped at simulated time 0.
    """
    from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Vector3
    from std_msgs.msg import Header
    from tf2_msgs.msg import TFMessage

    out = []

    def add(parent: str, child: str, pose) -> None:
        x, y, z, qx, qy, qz, qw = pose
        out.append(TransformStamped(
            header=Header(frame_id=parent), child_frame_id=child,
            transform=Transform(translation=Vector3(x=x, y=y, z=z),
                                rotation=Quaternion(x=qx, y=qy, z=qz, w=qw))))

    for ns, robot in zip(namespaces, frames, strict=True):
        add("map", f"{ns}/odom", (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0))
        for parent, child, pose in robot.joints:
            add(f"{ns}/{parent}", f"{ns}/{child}", pose)
    return TFMessage(transforms=out)


class SwarmTf:
    """The simulator's ``/tf``, ``/tf_static`` and ``robot_description`` publishers.

    Args:
        node: the simulator node.
        namespaces: (N) the robots' namespaces, without the leading slash.
        frames: (N) each robot's model frames (robots of one model may share one object).
    """

    def __init__(self, node, namespaces: Sequence[str], frames: Sequence[RobotFrames]):
        from std_msgs.msg import String
        from tf2_msgs.msg import TFMessage

        self.tf_pub = publisher(node, TFMessage, topics.TF)
        self.static_pub = publisher(node, TFMessage, topics.TF_STATIC)
        self.static_pub.publish(static_transforms(namespaces, frames))
        self.description_pubs = []
        for ns, robot in zip(namespaces, frames, strict=True):
            pub = publisher(node, String, topics.ROBOT_DESCRIPTION, ns)
            pub.publish(String(data=robot.description))
            self.description_pubs.append(pub)
        self._writer = TFMessageWriter((f"{ns}/odom", f"{ns}/{FOOTPRINT}") for ns in namespaces)

    def publish(self, t_ns: int, poses: np.ndarray) -> bool:
        """Every robot's ``odom`` -> ``base_footprint`` at ``t_ns`` [ns], if ``/tf`` has a reader.

        Args:
            t_ns: [ns] simulated time, the tick's stamp.
            poses: (N, 3) x [m], y [m], yaw [rad] in ``map`` (= each robot's ``odom``).

        Returns:
            Whether it was published.
        """
        if not self.tf_pub.get_subscription_count():
            return False
        self.tf_pub.publish(self._writer.write(t_ns, poses))
        return True
