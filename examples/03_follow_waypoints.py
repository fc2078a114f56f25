"""03 - Send a robot around the blockage with nav2's BasicNavigator.followWaypoints.

Start a swarm first (``swarm-up --swarm-size 3 --rtf 1``), then
``python examples/03_follow_waypoints.py [--namespace Srobot2]``.
"""

import argparse
import math
import time

import rclpy
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion
from rclpy.parameter import Parameter
from std_msgs.msg import Header

from swarm_commander.robot_navigator import BasicNavigator, NavFeedback, TaskResult

# x [m], y [m], yaw [rad] in map: below, left of and above the blockage of slim_blockage
WAYPOINTS = [(-4.5, -3.95, math.pi), (-6.4, 3.0, math.pi / 2), (-2.5, 8.4, 0.0)]


def make_pose(x, y, yaw):
    """A goal in ``map``: x, y [m], yaw [rad]."""
    return PoseStamped(header=Header(frame_id="map"), pose=Pose(position=Point(x=x, y=y),
                       orientation=Quaternion(z=math.sin(yaw / 2), w=math.cos(yaw / 2))))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--namespace", default="Srobot2")
    parser.add_argument("--timeout", type=float, default=600.0, help="[s] wall")
    args = parser.parse_args()
    rclpy.init()
    nav = BasicNavigator(namespace=args.namespace,
                         parameter_overrides=[Parameter("use_sim_time", value=True)])
    try:
        if not nav.waitUntilNav2Active(timeout_sec=30.0):
            return 1
        nav.followWaypoints([make_pose(*wp) for wp in WAYPOINTS])
        deadline, current = time.monotonic() + args.timeout, None
        while not nav.isTaskComplete():
            feedback = nav.getFeedback()
            if feedback and feedback.current_waypoint != current:
                current = feedback.current_waypoint
                print(f"executing waypoint {current + 1}/{len(WAYPOINTS)}", flush=True)
            if time.monotonic() > deadline:
                nav.cancelTask()
                break
        result, why = nav.getResult(), (nav.getFeedback() or NavFeedback()).reason
        print(f"result: {result.name}" + (f" ({why})" if why else ""))
        return 0 if result == TaskResult.SUCCEEDED else 1
    finally:
        nav.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
