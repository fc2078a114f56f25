"""The messaging baseline (swarm_bench.baseline): its layout, its config contract, one real run."""

from __future__ import annotations

import os
import re
from dataclasses import replace

import psutil
import pytest

from swarm_bench.baseline import BaselineConfig, baseline_layout, make_config, run_baseline
from swarm_common.errors import InputError
from swarm_up.args import default_processes, split_groups
from swarm_up.run_config import PER_ROBOT


def _cfg(n: int, commanders: bool = True) -> BaselineConfig:
    return BaselineConfig(robots=tuple(f"Srobot{i}" for i in range(1, n + 1)), duration_s=5.0,
                       summary_path="/tmp/x.json", map_yaml="/tmp/map.yaml",
                       commanders=commanders)


# ----------------------------------------------------------------------------------- pure parts
def test_config_round_trips_through_json():
    cfg = _cfg(3)
    assert BaselineConfig.decode(cfg.encode()) == cfg


@pytest.mark.parametrize("text", ["{}", "[1]", "not json", '{"robots": [], "bogus": 1}'])
def test_config_decode_rejects_other_json(text):
    with pytest.raises(InputError, match="^--config: not a baseline config"):
        BaselineConfig.decode(text)


def test_grouped_layout_uses_swarm_ups_groups():
    for k in (1, 2, 3):
        layout = baseline_layout(_cfg(7), "/tmp/c.json", k)
        groups = [p.args[p.args.index("--namespaces") + 1] for p in layout
                  if p.name.startswith("group_")]
        assert groups == [",".join(g) for g in split_groups(_cfg(7).robots, k)]


def test_per_robot_layout_has_a_navigator_and_a_commander_process_per_robot():
    layout = baseline_layout(_cfg(3), "/tmp/c.json", PER_ROBOT)
    names = [p.name for p in layout]
    assert names == ["listener", "nav_Srobot1", "nav_Srobot2", "nav_Srobot3",
                     "cmd_Srobot1", "cmd_Srobot2", "cmd_Srobot3", "sim"]
    assert layout[1].args[-2:] == ("Srobot1", "--navigators")
    assert layout[4].args[-2:] == ("Srobot1", "--commanders")


def test_grouped_layout_holds_navigators_and_commanders_together():
    layout = baseline_layout(_cfg(5), "/tmp/c.json", 2)
    assert [p.name for p in layout] == ["listener", "group_1", "group_2", "sim"]
    assert layout[1].args[-4:] == ("--namespaces", "Srobot1,Srobot3,Srobot5", "--navigators",
                                   "--commanders")
    assert layout[2].args[-4:-2] == ("--namespaces", "Srobot2,Srobot4")
    without = baseline_layout(_cfg(5, commanders=False), "/tmp/c.json", PER_ROBOT)
    assert len(without) == 1 + 5 + 1


def test_default_layout_is_swarm_ups():
    assert default_processes(1) == PER_ROBOT
    assert default_processes(8) == PER_ROBOT
    assert default_processes(9) == (os.cpu_count() or 1)


def test_make_config_takes_the_lidar_from_the_urdf(tmp_path):
    cfg = make_config(4, 12.0, tmp_path)
    assert cfg.robots == ("Srobot1", "Srobot2", "Srobot3", "Srobot4")
    assert (cfg.beams, cfg.lidar_rate_hz, cfg.lidar_every) == (360, 5.0, 2)  # turtlebot3 LDS-01
    assert cfg.range_max == pytest.approx(3.5)
    assert cfg.map_yaml.endswith("maps/slim_blockage.yaml")


# ------------------------------------------------------------------------------------- one run
@pytest.mark.node
def test_baseline_of_three_robots_delivers_every_tick(tmp_path):
    duration = 5.0
    cfg = replace(make_config(3, duration, tmp_path), goal_period_s=1.0)
    before = {p.pid for p in psutil.Process().children(recursive=True)}
    result = run_baseline(cfg, 2, tmp_path)  # two groups: navigators and commanders together
    logs = "\n".join(f"--- {p.name}\n{p.read_text()[-800:]}"
                     for p in sorted((tmp_path / "logs").glob("*.log")))
    assert result["exit_code"] == 0, logs
    assert result["ticks"] == round(duration * 10), logs
    assert result["sim_time_s"] == pytest.approx(duration)
    assert result["late_ticks"] == 0
    assert result["rtf"] > 0
    # the summary rounds wall_time_s to 1 ms (and the rates to 0.1 and 0.001), and five
    # simulated seconds of three baseline robots can take under 50 ms: allow that rounding
    wall = result["wall_time_s"]
    lo, hi = wall - 0.0005, wall + 0.0005
    assert 3 * result["ticks"] / hi - 0.05 <= result["robot_ticks_per_s"] \
        <= 3 * result["ticks"] / lo + 0.05, (result, wall)
    assert duration / hi - 0.0005 <= result["rtf"] <= duration / lo + 0.0005, (result, wall)
    assert result["processes"] == 2 and result["process_count"] == 4
    assert result["cpu_per_robot"] is not None and result["cpu_per_robot"] > 0
    # The commanders' goals went round: a 1 s goal each simulated second, no wait timed out.
    took = {m[1]: (int(m[2]), int(m[3])) for m in re.finditer(
        r"baseline: (\w+) took (\d+) goals, (\d+) goal-wait timeouts", logs)}
    assert set(took) == {"Srobot1", "Srobot2", "Srobot3"}, logs
    assert all(goals >= 3 and waits == 0 for goals, waits in took.values()), took
    # Every process stopped.
    after = {p.pid for p in psutil.Process().children(recursive=True)}
    assert after <= before


@pytest.mark.node
def test_the_baseline_commander_remakes_its_status_reader_until_it_hears_the_navigator():
    """As the real commander (eProsima/Fast-DDS#3822): a CI run's baseline held its second tick
    for 10 minutes when a commander's late reader got none of the navigator's latched status."""
    import time

    import rclpy
    from diagnostic_msgs.msg import DiagnosticStatus
    from geometry_msgs.msg import PoseStamped

    from swarm_bench.baseline_nodes import BaselineCommanderNode
    from swarm_common import topics
    from swarm_common.cdr import diagnostic_status
    from swarm_ros.qos import publisher, subscription
    from tests.support.ros import ros_context, spin_until

    ns = f"Sbase{os.getpid()}"
    with ros_context() as (ctx, ex):
        cmd = BaselineCommanderNode(ns, status_rematch_s=0.2, context=ctx)
        probe = rclpy.create_node("probe", namespace=f"/{ns}", context=ctx)
        ex.add_node(cmd)
        ex.add_node(probe)
        goals = []
        subscription(probe, PoseStamped, topics.GOAL_POSE, goals.append)
        end = time.monotonic() + 1.0
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        assert cmd.status_rematches >= 2  # nothing heard: the reader was made again
        status = publisher(probe, DiagnosticStatus, topics.NAV_STATUS)
        status.publish(diagnostic_status(0, f"{ns}/navigator", "IDLE", ns, {
            "state": "IDLE", "goal_id": "", "stamp": "0.100000000"}))
        spin_until(ex, lambda: goals, 10.0, "the commander's first goal")
        made = cmd.status_rematches
        end = time.monotonic() + 0.7
        while time.monotonic() < end:
            ex.spin_once(timeout_sec=0.05)
        assert cmd.status_rematches == made  # heard: no more readers
        assert probe.count_subscribers(f"/{ns}/nav_status") == 1  # the old readers are gone
