"""The metrics node keeps every status a navigator publishes, even when it falls behind.

A goal counts as reached when the recorder sees its ``SUCCEEDED`` status; the navigator publishes
the next goal's status one control tick later (0.1 s simulated, a few ms wall at RTF > 10).  A
reader that keeps only the newest status loses the ``SUCCEEDED`` whenever the listener thread is
late, and the run then reports fewer tasks than the commanders completed.
"""

from __future__ import annotations

import time

import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue

from swarm_common import topics
from swarm_common.nav_status import NavState, NavStatusRecord, encode
from swarm_common.stamps import format_stamp
from swarm_metrics.listener import MetricsListener
from swarm_ros.qos import profile
from tests.support.ros import ros_context

pytestmark = pytest.mark.node

GOALS = 40


def _status(state: NavState, goal: int, tick: int) -> DiagnosticStatus:
    record = NavStatusRecord(state=state, goal_id=format_stamp(goal, 0), stamp_ns=tick * 10**8,
                             goal=(1.0, 2.0, 0.0), distance_remaining=0.0,
                             navigation_time=float(goal), recoveries=0, holding_time=0.0,
                             goal_wait_timeouts=0, reason="")
    return DiagnosticStatus(message=state.value, name="Srobot1/navigator", hardware_id="Srobot1",
                            values=[KeyValue(key=k, value=v) for k, v in encode(record).items()])


def test_a_late_listener_still_counts_every_goal_reached():
    listener = MetricsListener(("Srobot1",), time.monotonic())
    listener.start()
    try:
        with ros_context() as (ctx, executor):
            node = rclpy.create_node("status_burst", context=ctx)
            pub = node.create_publisher(DiagnosticStatus, "/Srobot1/nav_status",
                                        profile(topics.LATCHED))
            deadline = time.monotonic() + 20.0
            while pub.get_subscription_count() < 1:
                assert time.monotonic() < deadline, "the metrics node never subscribed"
                executor.spin_once(timeout_sec=0.05)
            pub.publish(_status(NavState.IDLE, 0, 0))
            while listener.snapshot()[1] < 1:
                assert time.monotonic() < deadline, "the first status never arrived"
                time.sleep(0.02)
            # The listener is busy (its callbacks wait for the recorder's lock) while the
            # navigator reaches goal after goal, each followed by the next goal's first status.
            with listener.lock:
                for g in range(1, GOALS + 1):
                    pub.publish(_status(NavState.SUCCEEDED, g, 2 * g))
                    pub.publish(_status(NavState.DRIVING, g + 1, 2 * g + 1))
                time.sleep(0.5)
            last = format_stamp(GOALS + 1, 0)
            while True:
                with listener.lock:
                    rec = listener.recorder.per_robot["Srobot1"]
                    if rec.state == NavState.DRIVING and last in rec.holding_s:
                        break
                assert time.monotonic() < deadline, "the burst never arrived"
                time.sleep(0.02)
            node.destroy_node()
        with listener.lock:
            reached, aborted = listener.recorder.goal_totals()
        assert (reached, aborted) == (GOALS, 0)
    finally:
        listener.stop()
