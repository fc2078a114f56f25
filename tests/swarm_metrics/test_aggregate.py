"""Run figures from a synthetic status/event stream and simulator summary (pure, no ROS)."""

import ast
import dataclasses
import json
from pathlib import Path

import pytest

from swarm_common.nav_status import TOOK_ANOTHER
from swarm_common.sim_summary import SimSummary
from swarm_metrics.aggregate import RunFacts, RunRecorder, aggregate, load_sim_summary

ROBOTS = ("Srobot1", "Srobot2", "Srobot3")


def _status(state, goal="", nav_t=None, hold=None, reason=""):
    values = {"state": state, "goal_id": goal, "reason": reason}
    if nav_t is not None:
        values["navigation_time_s"] = str(nav_t)
    if hold is not None:
        values["holding_time_s"] = str(hold)
    return values


def _stream(rec: RunRecorder) -> None:
    """Three robots; readiness at 1.0, 1.5, 2.5 s wall; two goals reached by robot 1."""
    rec.on_status("Srobot1", _status("IDLE"), 1.0)
    rec.on_status("Srobot2", _status("IDLE"), 1.5)
    rec.on_status("Srobot1", _status("DRIVING", "10.000000000", 0.5), 3.0)
    rec.on_status("Srobot1", _status("HOLDING", "10.000000000", 4.0, hold=2.0), 3.5)
    rec.on_status("Srobot1", _status("HOLDING", "10.000000000", 6.0, hold=3.5), 4.0)
    rec.on_status("Srobot1", _status("SUCCEEDED", "10.000000000", 12.0, hold=3.5), 5.0)
    # re-published at 2 Hz, and again by a restarted navigator: counted once
    rec.on_status("Srobot1", _status("SUCCEEDED", "10.000000000", 12.5, hold=3.5), 5.5)
    rec.on_status("Srobot1", _status("SUCCEEDED", "10.000000000", 12.5, hold=3.5), 9.0)
    rec.on_status("Srobot1", _status("DRIVING", "30.000000000", 0.1), 6.0)
    rec.on_status("Srobot1", _status("SUCCEEDED", "30.000000000", 8.0, hold=1.0), 7.0)
    rec.on_status("Srobot3", _status("IDLE"), 2.5)
    rec.on_status("Srobot3", _status("PLANNING", "11.000000000"), 3.0)
    rec.on_status("Srobot3", _status("ABORTED", "11.000000000", 0.2, reason="goal in obstacle"),
                  3.1)
    rec.on_status("Srobot3", _status("ABORTED", "11.000000000", 0.2), 3.6)
    rec.on_event("spawn", {"robot": "Srobot1"})
    rec.on_event("spawn", {"robot": "Srobot2"})
    rec.on_event("collision", {"robot": "Srobot2", "other": "Srobot3", "x": "1", "y": "2"})
    rec.on_event("collision", {"robot": "/Srobot2", "other": "wall::link::box"})
    rec.on_event("late", {"robot": "Srobot2"})
    rec.on_clock(59.9)
    rec.on_clock(60.0)


SUMMARY = {
    "ticks": 1200,
    "sim_time_s": 60.0,
    "wall_time_s": 20.0,
    "late_ticks": 4,
    "collisions": {"robot_robot": 1, "robot_wall": 1},
    "min_separation_m": 0.42,
    "per_robot": {
        "Srobot1": {"distance_m": 12.5, "collisions": 0, "late_ticks": 1},
        "Srobot2": {"distance_m": 3.0, "collisions": 2, "late_ticks": 3},
        "Srobot3": {"distance_m": 0.0, "collisions": 1, "late_ticks": 0},
    },
}


SUMMARY_RECORD = SimSummary.from_dict(SUMMARY)


def _metrics(summary=SUMMARY_RECORD, **kw):
    rec = RunRecorder(robots=ROBOTS)
    _stream(rec)
    args = dict(world="slim_blockage", seed=7, coordination="decentralized", wall_time_s=22.0,
                resources={"cpu_percent": 150.0, "peak_rss_mb_per_robot": 35.0}, restarts=1)
    args.update(kw)
    return rec, aggregate(rec, summary, RunFacts(**args))


def test_readiness_and_spawn_to_ready():
    rec = RunRecorder(robots=ROBOTS)
    assert rec.ready_count == 0 and rec.spawn_to_ready_s() is None
    _stream(rec)
    assert rec.ready_count == 3
    assert rec.spawned_count == 2
    assert rec.not_ready() == []
    assert rec.spawn_to_ready_s() == pytest.approx(2.5)


def test_not_all_ready_gives_none():
    rec = RunRecorder(robots=ROBOTS)
    rec.on_status("Srobot1", _status("IDLE"), 1.0)
    assert rec.not_ready() == ["Srobot2", "Srobot3"]
    assert rec.spawn_to_ready_s() is None


def test_goal_counts_time_to_goal_and_holding():
    _, m = _metrics()
    assert m["goals_reached"] == 2
    assert m["tasks_completed"] == 2
    assert m["goals_aborted"] == 1
    # time to goal: navigation_time_s of the first SUCCEEDED status of each goal
    assert m["mean_time_to_goal_s"] == pytest.approx((12.0 + 8.0) / 2)
    # holding: latest value per goal, summed
    assert m["holding_time_s"] == pytest.approx(3.5 + 1.0)
    pr = m["per_robot"]
    assert pr["Srobot1"]["goals_reached"] == 2 and pr["Srobot1"]["holding_time_s"] == 4.5
    assert pr["Srobot3"]["goals_aborted"] == 1
    assert pr["Srobot1"]["ready_s"] == 1.0


def test_simulator_figures_and_rates():
    _, m = _metrics()
    assert m["robots"] == 3
    assert (m["world"], m["seed"], m["coordination"]) == ("slim_blockage", 7, "decentralized")
    assert m["sim_time_s"] == 60.0
    assert m["wall_time_s"] == 20.0  # the simulator's own wall time wins
    assert m["rtf"] == pytest.approx(3.0)
    assert m["robot_ticks_per_s"] == pytest.approx(1200 * 3 / 20.0)
    assert m["throughput_per_hour"] == pytest.approx(2 / (60.0 / 3600.0))
    assert m["collisions"] == {"robot_robot": 1, "robot_wall": 1}
    assert m["min_separation_m"] == 0.42
    assert m["late_ticks"] == 4
    assert m["cpu_percent"] == 150.0 and m["peak_rss_mb_per_robot"] == 35.0
    assert m["restarts"] == 1
    assert m["per_robot"]["Srobot2"]["distance_m"] == 3.0
    assert m["per_robot"]["Srobot2"]["collisions"] == 2
    json.dumps(m)  # serialisable


REQUIRED = ("robots world seed coordination sim_time_s wall_time_s rtf robot_ticks_per_s "
            "spawn_to_ready_s goals_reached goals_aborted tasks_completed throughput_per_hour "
            "collisions min_separation_m mean_time_to_goal_s holding_time_s late_ticks "
            "cpu_percent peak_rss_mb_per_robot restarts per_robot").split()


def test_required_keys_present_even_without_summary():
    rec, m = _metrics(summary=load_sim_summary(None)[0], wall_time_s=30.0)
    assert set(REQUIRED) <= set(m)
    for ns in ROBOTS:
        assert set(m["per_robot"][ns]) >= {"goals_reached", "goals_aborted", "collisions",
                                           "distance_m", "holding_time_s"}
    # fallbacks: /clock for simulated time, the orchestrator's wall time, events for collisions
    assert m["sim_time_s"] == 60.0
    assert m["wall_time_s"] == 30.0
    assert m["rtf"] == pytest.approx(2.0)
    assert m["collisions"] == {"robot_robot": 1, "robot_wall": 1}
    assert m["per_robot"]["Srobot2"]["collisions"] == 2
    assert m["per_robot"]["Srobot3"]["collisions"] == 1
    assert m["late_ticks"] == 1
    assert m["min_separation_m"] is None and m["robot_ticks_per_s"] is None


def test_anonymous_goals_count_on_transition():
    rec = RunRecorder(robots=("a",))
    for state in ("DRIVING", "SUCCEEDED", "SUCCEEDED", "DRIVING", "SUCCEEDED", "ABORTED"):
        rec.on_status("a", _status(state, nav_t=4.0), 0.0)
    m = aggregate(rec, load_sim_summary(None)[0], RunFacts(world="w", seed=0,
                  coordination="decentralized", wall_time_s=1.0))
    assert (m["goals_reached"], m["goals_aborted"]) == (2, 1)
    assert m["mean_time_to_goal_s"] == 4.0
    assert m["throughput_per_hour"] is None  # no simulated time known


def _waits(n):
    return {**_status("DRIVING", "g"), "goal_wait_timeouts": str(n)}


def test_goal_wait_timeouts_summed_over_restarts_and_reproducibility():
    rec = RunRecorder(robots=("a", "b"))
    for n in (0, 1, 2, 2):
        rec.on_status("a", _waits(n), 0.0)
    for n in (0, 1):  # a restarted navigator counts from 0 again
        rec.on_status("a", _waits(n), 0.0)
    rec.on_status("b", _waits("x"), 0.0)  # malformed: ignored
    clean = SimSummary(late_ticks=0, sim_time_s=10.0)
    m = aggregate(rec, clean, RunFacts(world="w", seed=0, coordination="decentralized",
                                       wall_time_s=1.0))
    assert m["goal_wait_timeouts"] == 3
    assert m["per_robot"]["a"]["goal_wait_timeouts"] == 3
    assert m["per_robot"]["b"]["goal_wait_timeouts"] == 0
    assert m["reproducible"] is False
    quiet = RunRecorder(robots=("a",))
    quiet.on_status("a", _waits(0), 0.0)
    args = dict(world="w", seed=0, coordination="decentralized", wall_time_s=1.0)
    assert aggregate(quiet, clean, RunFacts(**args))["reproducible"] is True
    assert aggregate(quiet, clean, RunFacts(restarts=1, **args))["reproducible"] is False
    late = dataclasses.replace(clean, late_ticks=2)
    assert aggregate(quiet, late, RunFacts(**args))["reproducible"] is False
    assert aggregate(quiet, SimSummary(sim_time_s=10.0), RunFacts(**args))["reproducible"] is None


def test_malformed_numbers_are_ignored():
    rec = RunRecorder(robots=("a",))
    rec.on_status("a", _status("SUCCEEDED", "g", nav_t="nan", hold="x"), 0.0)
    m = aggregate(rec, load_sim_summary(None)[0], RunFacts(world="w", seed=0,
                  coordination="decentralized", wall_time_s=1.0))
    assert m["goals_reached"] == 1
    assert m["mean_time_to_goal_s"] is None
    assert m["holding_time_s"] == 0.0


def test_load_sim_summary_tolerant(tmp_path: Path):
    summary, warnings = load_sim_summary(tmp_path / "missing.json")
    assert summary.sim_time_s is None and len(warnings) == 1 and "missing" in warnings[0]

    partial = tmp_path / "partial.json"
    partial.write_text(json.dumps({"ticks": 10, "sim_time_s": 1.0, "extra": 5}))
    summary, warnings = load_sim_summary(partial)
    assert summary.ticks == 10 and summary.extras["extra"] == 5 and summary.collisions is None
    assert len(warnings) == 1 and "collisions" in warnings[0]

    bad = tmp_path / "bad.json"
    bad.write_text("{not json")
    summary, warnings = load_sim_summary(bad)
    assert summary.ticks is None and len(warnings) == 1

    full = tmp_path / "full.json"
    full.write_text(json.dumps(SUMMARY))
    summary, warnings = load_sim_summary(full)
    assert warnings == [] and summary.ticks == 1200


def test_malformed_sim_summary_is_one_warning_naming_the_key(tmp_path: Path):
    bad = tmp_path / "sim_summary.json"
    bad.write_text(json.dumps({**SUMMARY, "late_ticks": "4"}))
    summary, warnings = load_sim_summary(bad)
    assert summary == SimSummary()  # every simulator figure null, none guessed
    assert warnings == [f"malformed simulator summary: {bad}: late_ticks: expected an integer, "
                        "got '4'; figures are null"]
    _, m = _metrics(summary=summary)
    assert (m["sim_time_s"], m["late_ticks"], m["collisions"]) == (
        60.0, 1, {"robot_robot": 1, "robot_wall": 1})  # the recorder's fallbacks


def test_aggregate_module_is_pure():
    tree = ast.parse(Path(__file__).resolve().parents[2].joinpath(
        "swarm_metrics", "aggregate.py").read_text())
    imported = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported |= {a.name.split(".")[0] for a in node.names}
        elif isinstance(node, ast.ImportFrom) and node.module:
            imported.add(node.module.split(".")[0])
    assert not {m for m in imported if m == "rclpy" or m.endswith("_msgs")}


# -------------------------------------------------------------- issue 11: tasks, comm, late goals
def _st(state, goal, stamp, nav_time):
    return {"state": state, "goal_id": goal, "stamp": stamp, "navigation_time_s": nav_time}


def test_late_goals_are_those_applied_after_the_tick_after_their_stamp():
    rec = RunRecorder(robots=("r1",))
    rec.on_status("r1", _st("DRIVING", "10.000000000", "10.100000000", "0.000"), 1.0)  # on time
    rec.on_status("r1", _st("DRIVING", "20.100000000", "20.200000000", "0.000"), 1.0)  # on time
    rec.on_status("r1", _st("DRIVING", "30.000000000", "30.400000000", "0.100"), 1.0)  # 30.3: late
    rec.on_status("r1", _st("DRIVING", "30.000000000", "30.900000000", "0.600"), 1.0)  # seen
    rec.on_status("r1", _st("SUCCEEDED", "30.000000000", "41.000000000", "10.700"), 1.0)
    assert rec.per_robot["r1"].late_goals == 1
    assert rec.per_robot["r1"].reached_at["30.000000000"] == 41.0
    m = aggregate(rec, SimSummary(), RunFacts(world="w", seed=0, coordination="decentralized",
                  wall_time_s=1.0))
    assert m["late_goals"] == 1 and m["task_times_s"] == [41.0]
    assert m["time_to_task_mean_s"] == pytest.approx(10.7)


def test_centralized_tasks_waiting_conflicts_and_communication_load():
    rec = RunRecorder(robots=("r1", "r2"))
    rec.on_clock(200.0)
    ev = [("reservation", {"robot": "r1", "action": "reserve", "resource": "workstation:A",
                           "t": "0.000000000", "epoch": "e"}),
          ("reservation", {"robot": "r2", "action": "reserve", "resource": "spot:A.0",
                           "t": "0.000000000", "epoch": "e"}),
          ("task", {"robot": "r1", "workstation": "A", "t_start": "0.000000000",
                    "t": "130.000000000", "duration_s": "130.000", "epoch": "e"}),
          ("reservation", {"robot": "r1", "action": "release", "resource": "workstation:A",
                           "t": "130.000000000", "epoch": "e"}),
          ("reservation", {"robot": "r2", "action": "release", "resource": "spot:A.0",
                           "t": "130.100000000", "epoch": "e"}),
          ("reservation", {"robot": "r2", "action": "reserve", "resource": "workstation:A",
                           "t": "130.100000000", "epoch": "e"}),
          ("reservation", {"robot": "r1", "action": "reserve", "resource": "spot:B.0",
                           "t": "150.000000000", "epoch": "e"}),
          ("coordinator", {"state": "up", "t": "0.000000000", "epoch": "e"}),
          ("lapse", {"robot": "r2", "workstation": "A", "reason": "lease",
                     "t": "190.500000000", "epoch": "e"})]
    for kind, values in ev:
        rec.on_event(kind, values)
    rec.on_comm("request", "r1", 200)
    rec.on_comm("assignment", "r2", 220)
    rec.on_comm("state", "", 60)  # one copy per robot
    rec.map_bytes = 1000
    m = aggregate(rec, SimSummary(), RunFacts(world="w", seed=0, coordination="centralized",
                  wall_time_s=1.0, map_deliveries={"r1": 1, "r2": 2}))
    assert m["tasks_completed"] == 1 and m["goals_reached"] == 0
    assert m["task_times_s"] == [130.0] and m["time_to_task_mean_s"] == 130.0
    # per robot too, its tasks and not its goals: r2 reaching its waiting spot is no task
    rec.on_status("r2", {"state": "SUCCEEDED", "goal_id": "5.000000000",
                         "stamp": "40.000000000", "navigation_time_s": "35.0"}, 1.0)
    m = aggregate(rec, SimSummary(), RunFacts(world="w", seed=0, coordination="centralized",
                  wall_time_s=1.0, map_deliveries={"r1": 1, "r2": 2}))
    assert m["per_robot"]["r1"]["task_times_s"] == [130.0]
    assert m["per_robot"]["r2"]["task_times_s"] == []
    assert m["per_robot"]["r2"]["goals_reached"] == 1
    assert m["task_times_s"] == [130.0]
    assert m["throughput_after_warmup_per_hour"] == pytest.approx(1 / (80 / 3600))
    assert m["coordinator_wait_s"] == pytest.approx(130.1 + 50.0)  # r1's spot open to the end
    assert m["reservation_conflicts"] == 0 and m["coordinator_starts"] == 1
    assert m["coordinator_lapses"] == [{"robot": "r2", "t_s": 190.5, "workstation": "A",
                                        "reason": "lease"}]
    c = m["comm"]
    assert (c["messages"], c["bytes"]) == (1 + 1 + 2 + 3, 200 + 220 + 120 + 3000)
    assert c["by_topic"]["map"] == {"messages": 3, "bytes": 3000, "messages_per_s": 0.015,
                                    "bytes_per_s": 15.0}
    assert c["per_robot"]["r2"]["bytes"] == 220 + 60 + 2000
    assert m["comm_bytes_per_s"] == pytest.approx(3540 / 200.0)
    assert m["per_robot"]["r1"]["tasks"] == 1 and m["per_robot"]["r2"]["comm_messages"] == 4


def test_coordinator_starts_count_each_epoch_once_from_either_source():
    """A start is heard as the "up" event or the latched state message (the event can be lost
    to a reader that matched the writer late); an epoch heard both ways counts once."""
    rec = RunRecorder(("r1",))
    rec.on_event("coordinator", {"state": "up", "t": "0.000000000", "epoch": "a"})
    rec.on_coordinator_up("a")
    assert rec.coordinator_starts == 1
    rec.on_coordinator_up("b")  # a restart whose "up" event went unheard
    assert rec.coordinator_starts == 2
    assert rec.coordinator_serving == {"a"}  # only the event says it answers requests
    m = aggregate(rec, SimSummary(), RunFacts(world="w", seed=0, coordination="centralized",
                  wall_time_s=1.0, map_deliveries={}))
    assert m["coordinator_starts"] == 2


# ------------------------------------------------ issue 9: tasks per window, workstation table
@pytest.mark.parametrize("times, sim_time, counts, full, ratio", [
    # 30 minutes: three whole windows; the ratio is over the two after the first
    ([10.0, 599.9, 600.0, 700.0, 1300.0, 1799.0], 1800.0, [2, 2, 2], 3, 1.0),
    ([10.0, 650.0, 700.0, 800.0, 1200.0], 1800.0, [1, 3, 1], 3, 0.5),
    # a short last window is counted, marked as not whole and left out of the ratio
    ([10.0, 700.0, 1250.0], 1300.0, [1, 1, 1], 2, 1.0),
    # a task at exactly the end counts in the last window
    ([1800.0], 1800.0, [0, 0, 1], 3, 0.0),
    # one whole window: no ratio; no tasks after the first window: no ratio (mean 0)
    ([5.0], 600.0, [1], 1, None),
    ([5.0], 1800.0, [1, 0, 0], 3, None),
    ([], 0.0, [], 0, None),
])
def test_tasks_per_window(times, sim_time, counts, full, ratio):
    from swarm_metrics.aggregate import tasks_per_window

    out = tasks_per_window(times, sim_time)
    assert out["tasks_per_window"] == counts and sum(counts) == len(times)
    assert out["task_window_s"] == 600.0 and out["task_windows_full"] == full
    assert out["task_window_ratio_min"] == (pytest.approx(ratio) if ratio is not None else None)


@pytest.mark.parametrize("counts, spread", [
    ([3, 0, 7, 0, 5], {"min": 0, "median": 3, "max": 7, "without_task": 2}),
    ([4, 6], {"min": 4, "median": 5.0, "max": 6, "without_task": 0}),
    ([], None),
])
def test_tasks_per_robot(counts, spread):
    from swarm_metrics.aggregate import tasks_per_robot

    assert tasks_per_robot(counts) == spread


def _goal(state, goal, x, y, nav_t=None, hold=None):
    values = _status(state, goal, nav_t, hold)
    values.update(goal_x=f"{x:.3f}", goal_y=f"{y:.3f}", goal_yaw="0.0000")
    return values


def test_workstation_table_matches_goals_to_the_nearest_docking_pose():
    from swarm_metrics.aggregate import workstation_table

    rec = RunRecorder(robots=("r1", "r2"))
    stations = {"loader1": (0.0, 0.0), "loader2": (5.0, 0.0), "unused": (9.0, 9.0)}
    # r1: two goals to loader1 (one reached after holding 4 s, one aborted), one to loader2
    rec.on_status("r1", _goal("DRIVING", "1.000000000", 0.1, -0.1, 0.0), 1.0)
    rec.on_status("r1", _goal("HOLDING", "1.000000000", 0.1, -0.1, 5.0, hold=4.0), 2.0)
    rec.on_status("r1", _goal("SUCCEEDED", "1.000000000", 0.1, -0.1, 20.0, hold=4.0), 3.0)
    rec.on_status("r1", _goal("ABORTED", "2.000000000", 0.0, 0.3, 0.1), 4.0)
    rec.on_status("r1", _goal("SUCCEEDED", "3.000000000", 4.8, 0.0, 10.0), 5.0)
    # r2: one goal to loader1 reached without holding, one to a waiting spot far from both
    rec.on_status("r2", _goal("SUCCEEDED", "4.000000000", 0.0, 0.0, 30.0, hold=0.0), 6.0)
    rec.on_status("r2", _goal("SUCCEEDED", "5.000000000", 2.5, 3.0, 7.0, hold=1.5), 7.0)
    rows = {row["name"]: row for row in workstation_table(rec, stations)}
    assert list(rows) == ["loader1", "loader2", "unused", "(other)"]
    one = rows["loader1"]
    assert (one["goals"], one["visits"], one["aborted"]) == (3, 2, 1)
    assert one["mean_time_to_goal_s"] == pytest.approx(25.0)
    assert one["holding_time_s"] == pytest.approx(4.0)
    assert one["mean_wait_s"] == pytest.approx(4.0 / 3)
    assert (rows["loader2"]["goals"], rows["loader2"]["visits"]) == (1, 1)
    assert rows["unused"]["goals"] == 0 and rows["unused"]["mean_wait_s"] is None
    assert (rows["(other)"]["goals"], rows["(other)"]["holding_time_s"]) == (1, 1.5)
    assert (rows["(other)"]["x"], rows["loader2"]["x"]) == (None, 5.0)
    # a goal whose navigator took another workstation counts where it was reached
    rec3 = RunRecorder(robots=("r1",))
    rec3.on_status("r1", _goal("HOLDING", "1.000000000", 0.0, 0.0, 5.0, hold=3.0), 1.0)
    took = {**_goal("SUCCEEDED", "1.000000000", 5.0, 0.0, 9.0, hold=3.0),
            "reason": f"{TOOK_ANOTHER}(5.000, 0.000), free while the goal at (0.000, 0.000) "
                      "was taken"}
    rec3.on_status("r1", took, 2.0)
    rec3.on_status("r1", took, 2.5)  # the same status again counts once
    assert rec3.per_robot["r1"].took_another == 1
    rows3 = {row["name"]: row for row in workstation_table(rec3, stations)}
    assert (rows3["loader1"]["goals"], rows3["loader2"]["goals"]) == (0, 1)
    assert (rows3["loader2"]["visits"], rows3["loader2"]["holding_time_s"]) == (1, 3.0)
    # no goal near no workstation: no (other) row
    rec2 = RunRecorder(robots=("r1",))
    rec2.on_status("r1", _goal("SUCCEEDED", "1.000000000", 5.4, 0.0, 3.0), 1.0)
    rows2 = workstation_table(rec2, stations)
    assert [r["name"] for r in rows2] == ["loader1", "loader2", "unused"]
    assert rows2[1]["visits"] == 1  # 0.4 m off: within the 0.5 m match


def test_metrics_carry_windows_and_the_workstation_table():
    rec = RunRecorder(robots=("r1",))
    rec.on_status("r1", _goal("DRIVING", "1.000000000", 1.0, 1.0, 0.0), 1.0)
    rec.on_status("r1", {**_goal("SUCCEEDED", "1.000000000", 1.0, 1.0, 12.0),
                         "stamp": "13.000000000"}, 2.0)
    m = aggregate(rec, SimSummary.from_dict({**SUMMARY, "sim_time_s": 1300.0}), RunFacts(world="w",
                  seed=0, coordination="decentralized", wall_time_s=1.0,
                  workstations={"ws": (1.0, 1.0)}))
    assert m["tasks_per_window"] == [1, 0, 0] and m["task_windows_full"] == 2
    assert m["tasks_per_robot"] == {"min": 1, "median": 1, "max": 1, "without_task": 0}
    assert m["workstations"][0]["name"] == "ws" and m["workstations"][0]["visits"] == 1
    json.dumps(m)  # the metrics file stays JSON
    m0 = aggregate(rec, SimSummary(), RunFacts(world="w", seed=0, coordination="decentralized",
                   wall_time_s=1.0))
    assert [r["name"] for r in m0["workstations"]] == ["(other)"]


def test_standstills_are_labelled_with_the_nearest_workstation_within_3_m():
    summary = SimSummary.from_dict({**SUMMARY, "standstills": [
        {"robot": "Srobot1", "start_s": 100.0, "duration_s": 75.0, "x": 0.5, "y": 2.5,
         "open": False},  # 2.5 m from loader1's dock, 0.6 m from its holding spot
        {"robot": "Srobot2", "start_s": 300.0, "duration_s": 61.5, "x": 20.0, "y": 0.0,
         "open": True},  # far from both
        {"robot": "Srobot3", "x": "nan", "y": 1.0},  # malformed: dropped
        "not an episode",
    ]})
    rec, m = _metrics(summary=summary, workstations={"loader1": (0.0, 0.0), "loader2": (6.0, 0.0)},
                      holding={"loader1": [(0.0, 3.0)], "loader2": []})
    assert [(e["robot"], e["near"]) for e in m["standstills"]] == [("Srobot1", "loader1"),
                                                                    ("Srobot2", None)]
    assert m["standstill_s"] == pytest.approx(136.5)
    _, m0 = _metrics()  # a summary without standstills
    assert m0["standstills"] == [] and m0["standstill_s"] == 0.0


def test_metrics_say_where_the_robots_spawned_and_what_of_the_world_was_skipped():
    spawn = ("in the largest free area (no points-of-interest file), x 3.05..5.05 m, "
             "y -2.95..-2.95 m, first at (3.05, -2.95)")
    summary = SimSummary.from_dict({**SUMMARY, "spawn": spawn,
                                    "world_skipped": ["actor 'walker'", "road 'lane'"]})
    _, m = _metrics(summary=summary)
    assert m["spawn"] == spawn
    assert m["world_skipped"] == ["actor 'walker'", "road 'lane'"]
    json.dumps(m)
    _, whole = _metrics(summary=SimSummary.from_dict({**SUMMARY, "spawn": spawn,
                                                      "world_skipped": []}))
    assert whole["world_skipped"] == []  # the world loaded whole
    _, m0 = _metrics()  # a summary without them (or none at all): unknown
    assert m0["spawn"] is None and m0["world_skipped"] is None
    _, bad = _metrics(summary=SimSummary.from_dict({**SUMMARY, "spawn": 3,
                                                    "world_skipped": "actor"}))
    assert bad["spawn"] is None and bad["world_skipped"] is None
