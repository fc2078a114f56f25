"""``swarm-up`` with a test harness on the ``simulation_interfaces`` services, end to end.

A run paused through ``/swarm_sim/set_simulation_state``, stepped through a stretch with
``/swarm_sim/step_simulation`` (its navigators and commanders waiting meanwhile) and played
again gives the same simulated figures as the same run left alone: a pause costs wall time only
(swarm_sim/sim_control.py).
"""

from __future__ import annotations

import time

import pytest
import rclpy
from simulation_interfaces import srv
from simulation_interfaces.msg import Result, SimulationState

from tests.support.ros import ros_context, spin_until
from tests.swarm_sim.test_node_ros_standards import Services
from tests.test_e2e_swarm_up import (
    EXIT_SLACK_S,
    READY_TIMEOUT_S,
    SwarmUp,
    _diff,
    _run_to_end,
    _simulated,
)

pytestmark = pytest.mark.e2e

ARGS = ["--swarm-size", "4", "--commanders", "--rtf", "0", "--duration", "90", "--seed", "4"]
TICK_NS = 100_000_000


def test_a_run_paused_and_stepped_through_a_stretch_is_the_run_left_alone(tmp_path):
    _, plain, diag1 = _run_to_end(ARGS, tmp_path, "plain", 90.0)
    with SwarmUp(ARGS, tmp_path, "stepped") as run, ros_context() as (ctx, ex):
        node = rclpy.create_node("harness", context=ctx)
        ex.add_node(node)
        sim = Services(node, ex)
        run.wait_for_stdout(r"navigators ready: 4/4", READY_TIMEOUT_S)
        # mid-run, robots under way: pause once simulated time has passed 20 s
        spin_until(ex, lambda: sim.pose("Srobot1")[0] >= 20 * 10**9, 120, "t = 20 s")
        assert sim.set_state(SimulationState.STATE_PAUSED).result == Result.RESULT_OK
        held = sim.pose("Srobot1")
        assert 0 < held[0] < 90 * 10**9, f"paused at {held[0]} ns: the run was over\n" \
            + run.diagnostics()
        for _ in range(4):  # 4 x 5 ticks, with wall time between them
            time.sleep(0.5)
            step = sim.call("step_simulation", srv.StepSimulation,
                            srv.StepSimulation.Request(steps=5))
            assert step.result.result == Result.RESULT_OK
        assert sim.pose("Srobot1")[0] == held[0] + 20 * TICK_NS
        time.sleep(2.0)
        assert sim.set_state(SimulationState.STATE_PLAYING).result == Result.RESULT_OK
        code = run.wait(READY_TIMEOUT_S + 90.0 + EXIT_SLACK_S)
        diag2 = run.diagnostics()
        assert code == 0, f"swarm-up exited with {code}\n{diag2}"
        stepped = run.metrics()
    for m in (plain, stepped):
        assert m["reproducible"] is True and m["tasks_completed"] > 0
    a, b = _simulated(plain), _simulated(stepped)
    for m in (a, b):  # copies of a message sent again for want of an answer: wall-clock timing
        m["comm"] = {k: v for k, v in m["comm"].items() if k != "resent"}
    diffs = _diff(a, b)
    assert not diffs, ("pausing and stepping changed the simulated run:\n  "
                       + "\n  ".join(diffs[:30]) + f"\nplain:\n{diag1}\nstepped:\n{diag2}")
