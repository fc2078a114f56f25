"""04 - A custom route for several robots: one BasicNavigator per namespace, in one script.

Start a swarm first (``swarm-up --swarm-size 3 --rtf 1``), then
``python examples/04_custom_route_several_robots.py``.
"""

import math
import time

import rclpy
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion
from rclpy.parameter import Parameter
from std_msgs.msg import Header

from swarm_commander.robot_navigator import BasicNavigator, TaskResult

TIMEOUT = 600.0  # [s] wall
ROUTES = {  # namespace -> its stops: (name, x [m], y [m], yaw [rad]) in map (slim_blockage.yaml)
    "Srobot1": [("loader2", -7.74575, -1.38526, math.pi),
                ("loader1", -7.74575, -3.57766, math.pi)],
    "Srobot2": [("unload", 5.0, 5.0, 0.0), ("shipping", 7.01559, 6.99901, 0.0)],
    "Srobot3": [("east", 8.0, 2.0, 0.0), ("centre", 3.0, 3.0, math.pi)],
}


def make_pose(x, y, yaw):
    """A goal in ``map``: x, y [m], yaw [rad]."""
    return PoseStamped(header=Header(frame_id="map"), pose=Pose(position=Point(x=x, y=y),
                       orientation=Quaternion(z=math.sin(yaw / 2), w=math.cos(yaw / 2))))


def main():
    rclpy.init()
    sim_time = [Parameter("use_sim_time", value=True)]
    navs = {ns: BasicNavigator(namespace=ns, parameter_overrides=sim_time) for ns in ROUTES}
    todo = {ns: list(stops) for ns, stops in ROUTES.items()}  # stops not reached yet
    try:
        if not all(nav.waitUntilNav2Active(timeout_sec=30.0) for nav in navs.values()):
            return 1
        for ns, nav in navs.items():
            nav.goToPose(make_pose(*todo[ns][0][1:]))
        deadline, failed = time.monotonic() + TIMEOUT, False
        while any(todo.values()) and not failed and time.monotonic() < deadline:
            for ns, nav in navs.items():  # isTaskComplete() spins that one node for <= 0.1 s
                if not todo[ns] or not nav.isTaskComplete():
                    continue
                if nav.getResult() != TaskResult.SUCCEEDED:
                    print(f"{ns} did not reach {todo[ns][0][0]}: {nav.getResult().name}")
                    failed = True
                    break
                print(f"{ns} arrived at {todo[ns].pop(0)[0]}", flush=True)
                if todo[ns]:
                    nav.goToPose(make_pose(*todo[ns][0][1:]))
        for nav in navs.values():
            nav.cancelTask()  # stops a robot still driving (after a failure or the timeout)
        return 1 if any(todo.values()) else 0
    finally:
        for nav in navs.values():
            nav.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
