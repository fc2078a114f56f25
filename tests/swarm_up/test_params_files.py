"""One navigator params file per namespace, rooted at /<ns>/navigator, as ROS reads it."""

import sys
from dataclasses import replace
from pathlib import Path

import pytest
import yaml

from swarm_common.errors import InputError
from swarm_up.args import split_groups
from swarm_up.children import child_specs
from swarm_up.run_config import RunConfig
from swarm_up.rundir import RunError, load_nav_template, write_params_files

TEMPLATE = """\
navigator:
  ros__parameters:
    control_rate: 10.0          # [Hz]
    goal_tolerance_xy: 0.25     # [m]
    holding_wait: 2.0           # [s]
    planner_allow_unknown: false
"""


@pytest.fixture
def cfg(tmp_path) -> RunConfig:
    world = tmp_path / "w.world"
    world.write_text("<sdf version='1.6'><world name='w'/></sdf>")
    poi = tmp_path / "w.yaml"
    poi.write_text("workstations: []\n")
    return RunConfig(
        robots=("Srobot1", "Srobot2", "Srobot3"),
        name_prefix="Srobot",
        world_path=world,
        world_name="w",
        robot="turtlebot3_waffle",
        map_path=tmp_path / "map.yaml",
        poi_path=poi,
        seed=4,
        rtf=0.0,
        duration=30.0,
        commanders=True,
        coordination="decentralized",
        metrics_path=None,
        groups=None,
        gui=False,
        run_dir=tmp_path / "run",
        ready_timeout=60.0,
        nav_template=tmp_path / "navigator.yaml",
    )


@pytest.fixture
def template(cfg) -> dict:
    cfg.nav_template.write_text(TEMPLATE)
    return load_nav_template(cfg.nav_template)


def test_one_file_per_namespace_rooted_at_ns_navigator(cfg, template):
    files = write_params_files(cfg, template)
    assert [f.name for f in files] == ["Srobot1.yaml", "Srobot2.yaml", "Srobot3.yaml"]
    assert sorted(p.name for p in (cfg.run_dir / "params").iterdir()) == [f.name for f in files]
    for i, (ns, path) in enumerate(zip(cfg.robots, files, strict=True), start=1):
        data = yaml.safe_load(path.read_text())
        assert list(data) == [f"/{ns}/navigator"]
        params = data[f"/{ns}/navigator"]["ros__parameters"]
        # the template's keys, unchanged
        assert params["control_rate"] == 10.0 and params["goal_tolerance_xy"] == 0.25
        assert params["planner_allow_unknown"] is False
        # the keys swarm-up adds
        assert params["use_sim_time"] is True
        assert params["robot_name"] == ns and params["robot_index"] == i
        assert params["poi_file"] == str(cfg.poi_path)
        assert params["map_yaml_path"] == ""  # navigators take the map from /map
        assert params["robot"] == "turtlebot3_waffle"
        # the commanders are in the lockstep: no wait for them has a wall-clock limit
        assert params["wait_for_commander"] is True and params["hold_goal_end"] is False
        assert "goal_wait_timeout" not in params  # only for a commander outside the lockstep
        assert params["wait_for_status_readers"] == 2  # the metrics listener and the commander
        assert params["wait_for_cmd_vel_readers"] == 1  # the simulator


def test_without_commanders_no_start_gate_and_no_lockstep_commander(cfg, template):
    """With commanders (above) a loaded machine must not turn a late goal into a different run;
    without, a user's commander may have nothing more to send: the navigator's own
    goal_wait_timeout (0.5 s) bounds its wait."""
    params = yaml.safe_load(write_params_files(replace(cfg, commanders=False), template)[0]
                            .read_text())["/Srobot1/navigator"]["ros__parameters"]
    assert params["wait_for_commander"] is False and params["hold_goal_end"] is False
    assert params["wait_for_status_readers"] == 1  # the metrics listener


def test_centralized_commanders_hold_the_end_of_each_goal(cfg, template):
    """Under --coordination centralized the tick at which a goal ends waits for the
    commander's word: the coordinator then has every request of that tick."""
    params = yaml.safe_load(write_params_files(replace(cfg, coordination="centralized"),
                                               template)[0].read_text())[
        "/Srobot1/navigator"]["ros__parameters"]
    assert params["wait_for_commander"] is True and params["hold_goal_end"] is True


@pytest.mark.parametrize(("topics", "status_readers", "cmd_vel_readers"), [
    (None, 3, 2),  # every topic: the recorder reads both
    ("cmd_vel", 2, 2),
    ("nav_status|clock", 3, 1),
    ("ground_truth", 2, 1),
])
def test_a_recording_adds_the_recorder_to_the_readers_the_first_answer_waits_for(
        cfg, template, tmp_path, topics, status_readers, cmd_vel_readers):
    """The recorder must not miss a robot's first commands or statuses: the first answer waits
    for it too, on the topics that ``--record-topics`` records."""
    cfg = replace(cfg, record_path=tmp_path / "run.mcap", record_topics=topics)
    for path in write_params_files(cfg, template):
        params = next(iter(yaml.safe_load(path.read_text()).values()))["ros__parameters"]
        assert params["wait_for_status_readers"] == status_readers, path.name
        assert params["wait_for_cmd_vel_readers"] == cmd_vel_readers, path.name


@pytest.mark.parametrize(("coordination", "policy", "expected"), [
    ("decentralized", (), (1, 3, 2.5)),
    ("centralized", (), (0, 0, 0.0)),
    ("centralized", ("--policy", "pipelined"), (0, 0, 0.0)),
    ("centralized", ("--policy", "pipelined", "--queue-at", "holding"), (1, 3, 0.0))])
def test_centralized_runs_leave_the_queueing_to_the_coordinator(cfg, template, coordination,
                                                                policy, expected):
    """Under --coordination centralized the navigator's own queue and congestion rules are off
    (the coordinator queues the robots), and so is taking another workstation (the coordinator
    chooses one); with the pipelined policy's --queue-at holding the navigators queue, so only
    the last is off; decentralized runs keep the template's values."""
    cfg = replace(cfg, coordination=coordination, coordinator_args=policy)
    template = {**template, "crowd_limit": 1, "congestion_limit": 3,
                "swap_range": 2.5}  # the defaults' values
    for path in write_params_files(cfg, template):
        params = next(iter(yaml.safe_load(path.read_text()).values()))["ros__parameters"]
        assert (params["crowd_limit"], params["congestion_limit"],
                params["swap_range"]) == expected, path.name


def test_missing_poi_and_map_give_empty_strings(cfg, template):
    cfg = replace(cfg, poi_path=None, map_path=None)
    params = yaml.safe_load(write_params_files(cfg, template)[0].read_text())
    params = params["/Srobot1/navigator"]["ros__parameters"]
    assert params["poi_file"] == "" and params["map_yaml_path"] == ""


@pytest.mark.node  # a participant: with the tests that start ROS (tests/conftest.py)
def test_ros_reads_the_file_for_the_namespaced_node(cfg, template):
    """rcl parses the file and gives its values to /Srobot2/navigator only."""
    import rclpy
    from rclpy.node import Node

    path = write_params_files(cfg, template)[1]
    ctx = rclpy.Context()
    rclpy.init(args=["--ros-args", "-r", "__ns:=/Srobot2", "--params-file", str(path)],
               context=ctx)
    try:
        node = Node("navigator", context=ctx, automatically_declare_parameters_from_overrides=True)
        try:
            assert node.get_fully_qualified_name() == "/Srobot2/navigator"
            assert node.get_parameter("robot_name").value == "Srobot2"
            assert node.get_parameter("robot_index").value == 2
            assert node.get_parameter("use_sim_time").value is True
            assert node.get_parameter("goal_tolerance_xy").value == 0.25
        finally:
            node.destroy_node()
    finally:
        ctx.try_shutdown()


def test_template_errors(tmp_path):
    with pytest.raises(RunError, match="navigator.yaml: navigator parameter template missing"):
        load_nav_template(tmp_path / "navigator.yaml")
    bad = tmp_path / "bad.yaml"
    bad.write_text("planner:\n  ros__parameters: {}\n")
    with pytest.raises(InputError, match="top-level key must be 'navigator'"):
        load_nav_template(bad)
    bad.write_text("navigator: [1, 2]\n")
    with pytest.raises(InputError, match="ros__parameters"):
        load_nav_template(bad)
    bad.write_text("navigator: {ros__parameters: {a: 1}}\n")
    assert load_nav_template(bad) == {"a": 1}


@pytest.mark.parametrize(
    ("n", "k", "sizes"),
    [(10, 3, [4, 3, 3]), (100, 2, [50, 50]), (3, 5, [1, 1, 1]), (7, 1, [7])],
)
def test_split_groups(n, k, sizes):
    robots = tuple(f"R{i}" for i in range(1, n + 1))
    groups = split_groups(robots, k)
    assert [len(g) for g in groups] == sizes
    assert sorted(sum(groups, ()), key=lambda r: int(r[1:])) == list(robots)
    for g, group in enumerate(groups):  # dealt round-robin: robot i goes to group i % k
        assert group == robots[g::len(groups)]
    if n >= 4 and k == 2:
        assert groups[0][:2] == ("R1", "R3") and groups[1][:2] == ("R2", "R4")


def test_child_commands_per_robot(cfg):
    specs = child_specs(cfg)
    names = [s.name for s in specs]
    assert names == ["sim", "nav_Srobot1", "nav_Srobot2", "nav_Srobot3",
                     "cmd_Srobot1", "cmd_Srobot2", "cmd_Srobot3"]
    sim = specs[0]
    assert not sim.restart and sim.kind == "sim"
    argv = list(sim.argv)
    for flag, value in [("--world", str(cfg.world_path)), ("--robot", "turtlebot3_waffle"),
                        ("--swarm-size", "3"), ("--name-prefix", "Srobot"), ("--seed", "4"),
                        ("--wait-for", "3"),
                        ("--rtf", "0.0"), ("--duration", "30.0"), ("--map", str(cfg.map_path)),
                        ("--summary", str(cfg.run_dir / "sim_summary.json"))]:
        assert argv[argv.index(flag) + 1] == value
    assert "--gui" not in argv
    nav = list(specs[2].argv)
    assert nav[-5:] == ["--ros-args", "-r", "__ns:=/Srobot2", "--params-file",
                        str(cfg.run_dir / "params" / "Srobot2.yaml")]
    assert specs[2].log_path == cfg.run_dir / "logs" / "nav_Srobot2.log"
    cmd = list(specs[5].argv)
    assert cmd[-9:] == ["Srobot2", "--world", str(cfg.world_path), "--seed", "4",
                        "--wait-timeout", repr(cfg.ready_timeout), "--service-time", "0.0"]
    assert all(s.restart for s in specs[1:])


def test_child_commands_grouped(cfg):
    cfg = replace(cfg, groups=split_groups(cfg.robots, 2), gui=True, duration=None)
    specs = child_specs(cfg)
    assert [s.name for s in specs] == ["sim", "group_1", "group_2"]
    assert "--gui" in specs[0].argv and "--duration" not in specs[0].argv
    g1 = list(specs[1].argv)
    assert g1[:3] == [sys.executable, "-m", "swarm_up.group"]
    assert g1[g1.index("--namespaces") + 1] == "Srobot1,Srobot3"
    assert g1[g1.index("--params-dir") + 1] == str(Path(cfg.run_dir) / "params")
    assert "--commanders" in g1 and g1[g1.index("--seed") + 1] == "4"
    assert specs[2].robots == ("Srobot2",)
