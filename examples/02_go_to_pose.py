"""02 - Send one robot to a workstation with nav2's BasicNavigator.goToPose.

Start a swarm first (``swarm-up --swarm-size 3 --rtf 1``), then
``python examples/02_go_to_pose.py [--namespace Srobot1]``.
"""

import argparse
import math
import time

import rclpy
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion
from rclpy.parameter import Parameter
from std_msgs.msg import Header

from swarm_commander.robot_navigator import BasicNavigator, NavFeedback, TaskResult


def make_pose(x, y, yaw):
    """A goal in ``map``: x, y [m], yaw [rad]."""
    return PoseStamped(header=Header(frame_id="map"), pose=Pose(position=Point(x=x, y=y),
                       orientation=Quaternion(z=math.sin(yaw / 2), w=math.cos(yaw / 2))))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--namespace", default="Srobot1")
    parser.add_argument("--timeout", type=float, default=600.0, help="[s] wall")
    args = parser.parse_args()
    rclpy.init()
    nav = BasicNavigator(namespace=args.namespace,
                         parameter_overrides=[Parameter("use_sim_time", value=True)])
    try:
        if not nav.waitUntilNav2Active(timeout_sec=30.0):
            return 1
        nav.goToPose(make_pose(-7.74575, 0.97297, math.pi))  # loader3 in slim_blockage.yaml
        deadline, i = time.monotonic() + args.timeout, 0
        while not nav.isTaskComplete():  # waits up to 0.1 s for the task to end
            i += 1
            feedback = nav.getFeedback()
            if feedback and i % 10 == 0:
                print(f"{feedback.state}: {feedback.distance_remaining:.2f} m to go after "
                      f"{feedback.navigation_time.sec} s", flush=True)
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
