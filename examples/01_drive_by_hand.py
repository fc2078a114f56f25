"""01 - Drive a robot by hand: TwistStamped with a zero stamp on <ns>/cmd_vel; watch <ns>/odom.

Start the simulator alone first (a navigator's commands would replace yours):
``swarm-sim --swarm-size 1``, then ``python examples/01_drive_by_hand.py``.
"""

import argparse
import math
import time

import rclpy
from geometry_msgs.msg import TwistStamped
from nav_msgs.msg import Odometry
from rclpy.parameter import Parameter

DISTANCE = 0.3  # [m] to drive forward (a robot spawns facing -x)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--namespace", default="Srobot1")
    parser.add_argument("--timeout", type=float, default=30.0, help="[s] wall")
    args = parser.parse_args()
    rclpy.init()
    node = rclpy.create_node("drive_by_hand", parameter_overrides=[
        Parameter("use_sim_time", value=True)])
    pub = node.create_publisher(TwistStamped, f"/{args.namespace}/cmd_vel", 10)
    odom = {}  # "start", "now": (x, y) [m] in odom; "v": forward speed [m/s]

    def on_odom(msg):
        p = msg.pose.pose.position
        odom.setdefault("start", (p.x, p.y))
        odom.update(now=(p.x, p.y), v=msg.twist.twist.linear.x)

    node.create_subscription(Odometry, f"/{args.namespace}/odom", on_odom, 10)
    cmd = TwistStamped()  # header.stamp stays zero: "apply now, hold until replaced"
    cmd.twist.linear.x = 0.2  # [m/s]
    moved, sent, deadline = 0.0, 0.0, time.monotonic() + args.timeout
    try:
        while time.monotonic() < deadline:
            rclpy.spin_once(node, timeout_sec=0.05)
            moved = math.dist(odom["start"], odom["now"]) if odom else 0.0
            if moved >= DISTANCE and cmd.twist.linear.x != 0.0:
                cmd.twist.linear.x, sent = 0.0, 0.0  # far enough: send the stop right away
            elif moved >= DISTANCE and abs(odom["v"]) < 1e-3:
                print(f"stopped after {moved:.2f} m")
                return 0
            if odom and time.monotonic() - sent > 0.2:  # re-send: the first may be too early
                pub.publish(cmd)
                sent = time.monotonic()
                print(f"odom: x {odom['now'][0]:.2f} m, y {odom['now'][1]:.2f} m, "
                      f"v {odom['v']:.2f} m/s; moved {moved:.2f} m", flush=True)
        print(f"FAILED: moved {moved:.2f} m, not stopped after {args.timeout:g} s")
        return 1
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


if __name__ == "__main__":
    raise SystemExit(main())
