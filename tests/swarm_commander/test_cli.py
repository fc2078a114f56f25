"""``swarm-commander`` as a user runs it (subprocess), and CommanderRunner in-process.

The navigator is the fake one (wall clock), so the commander runs with
``--ros-args -p use_sim_time:=false``.
"""

from __future__ import annotations

import itertools
import os
import queue
import re
import signal
import subprocess
import sys
import threading
import time

import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter

from swarm_commander.cli import CommanderConfig, CommanderRunner
from swarm_commander.robot_navigator import BasicNavigator
from swarm_commander.route import FixedRoute, RandomRoute, route_rng, stops_from_workstations
from swarm_scene.poi import load_poi

from .fake_navigator import running_fake_navigator

pytestmark = pytest.mark.node


_COUNTER = itertools.count(1)
WALL = ["--ros-args", "-p", "use_sim_time:=false"]

WORLD_SDF = """\
<?xml version="1.0"?>
<sdf version="1.6">
  <world name="tiny">
    <model name="wall">
      <static>true</static>
      <pose>0 3 0.5 0 0 0</pose>
      <link name="link">
        <collision name="collision">
          <geometry><box><size>4 0.2 1</size></box></geometry>
        </collision>
      </link>
    </model>
  </world>
</sdf>
"""

POI_YAML = """\
frame_id: map
workstations:
  - {name: loader1, x: 1.0, y: 0.0, yaw: 0.0}
  - {name: loader2, x: 2.0, y: 1.0, yaw: 1.5708}
  - {name: unload, x: -1.0, y: -1.0, yaw: 3.14159}
"""
STATIONS = {"loader1": (1.0, 0.0), "loader2": (2.0, 1.0), "unload": (-1.0, -1.0)}
REACHED = re.compile(r"^\[(\w+)\] task (\d+): reached (\w+) in (\d+\.\d) s \(wall\)$")


@pytest.fixture
def ns():
    return f"Tcli{next(_COUNTER)}"


@pytest.fixture
def world(tmp_path):
    path = tmp_path / "tiny.world"
    path.write_text(WORLD_SDF)
    (tmp_path / "tiny.yaml").write_text(POI_YAML)
    return path


@pytest.fixture
def context():
    ctx = Context()
    rclpy.init(context=ctx)
    yield ctx
    rclpy.try_shutdown(context=ctx)


def commander(*args, timeout=30.0) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "swarm_commander.cli", *args],
                          capture_output=True, text=True, timeout=timeout)


def test_loops_once_over_every_workstation(context, ns, world):
    with running_fake_navigator(ns, context, drive_time=0.2) as fake:
        res = commander(ns, "--world", str(world), "--loops", "1", "--seed", "4", *WALL)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert len(lines) == 4, res.stdout
    arrivals = [REACHED.match(line) for line in lines[:3]]
    assert all(arrivals), res.stdout
    assert [m.group(1) for m in arrivals] == [ns] * 3
    assert [int(m.group(2)) for m in arrivals] == [1, 2, 3]
    assert sorted(m.group(3) for m in arrivals) == sorted(STATIONS)
    assert all(0.1 <= float(m.group(4)) < 5.0 for m in arrivals)
    assert lines[3].startswith(f"[{ns}] summary: 3 tasks: 3 reached, 0 failed, 0 canceled in ")
    # the goals sent are the workstations' poses, in the printed order
    assert [(x, y) for _, x, y in fake.goals] == [STATIONS[m.group(3)] for m in arrivals]
    assert res.stderr == ""


def test_same_seed_same_order(context, ns, world):
    orders = []
    for _ in range(2):
        with running_fake_navigator(ns, context, drive_time=0.05):
            res = commander(ns, "--world", str(world), "--loops", "2", "--seed", "9", *WALL)
        assert res.returncode == 0, res.stderr
        orders.append([REACHED.match(line).group(3) for line in res.stdout.splitlines()[:-1]])
    assert orders[0] == orders[1] and len(orders[0]) == 6
    assert orders[0][2] != orders[0][3]  # no immediate repeat across the loop boundary


def test_aborted_goal_is_printed_and_the_commander_moves_on(context, ns, world, tmp_path):
    route = tmp_path / "route.yaml"
    route.write_text("waypoints:\n  - loader1\n  - {name: far, x: 150, y: 0, yaw: 0}\n"
                     "  - unload\n")
    with running_fake_navigator(ns, context, drive_time=0.2):
        res = commander(ns, "--world", str(world), "--route", str(route), "--loops", "1", *WALL)
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert REACHED.match(lines[0]).group(3) == "loader1"
    assert re.match(rf"^\[{ns}\] task 2: failed to reach far after \d+\.\d s \(wall\): "
                    r"goal outside the map$", lines[1]), lines[1]
    assert REACHED.match(lines[2]).group(3) == "unload"
    assert "3 tasks: 2 reached, 1 failed, 0 canceled" in lines[3]


def test_numeric_ns_uses_the_name_prefix(context, world):
    prefix = f"Tpre{next(_COUNTER)}x"
    with running_fake_navigator(f"{prefix}7", context, drive_time=0.05):
        res = commander("7", "--name-prefix", prefix, "--world", str(world), "--loops", "1",
                        *WALL)
    assert res.returncode == 0, res.stderr
    assert res.stdout.startswith(f"[{prefix}7] task 1: reached ")


def test_unknown_namespace_exits_2_within_the_wait_timeout(ns, world):
    t0 = time.monotonic()
    res = commander(ns, "--world", str(world), "--wait-timeout", "1", *WALL)
    elapsed = time.monotonic() - t0
    assert res.returncode == 2
    assert res.stderr.splitlines() == [
        f"swarm-commander: error: {ns}: no navigator answered on /{ns}/nav_status within 1 s "
        "(0 writer(s) matched, the reader made again 0 time(s))"]
    assert res.stdout == ""
    assert 1.0 <= elapsed < 10.0


def test_a_coordinated_commander_without_a_navigator_exits_2_saying_what_it_matched(ns, world):
    """``--coordinated`` with neither coordinator nor navigator: it starts anyway after the
    wait for the coordinator, connects anyway after the wait for the link, and gives up after
    the wait for the navigator, naming the ``nav_status`` writers its reader matched."""
    res = commander(ns, "--world", str(world), "--coordinated", "--wait-timeout", "1", *WALL)
    assert res.returncode == 2, res.stderr
    assert res.stderr.splitlines()[-1] == (
        f"swarm-commander: error: {ns}: no navigator answered on /{ns}/nav_status within 1 s "
        "(0 writer(s) matched, the reader made again 0 time(s))"), res.stderr
    assert res.stdout.splitlines() == [
        f"[{ns}] no coordinator after 1 s; starting anyway",
        f"[{ns}] not linked to the coordinator after 1 s; connecting to the navigator anyway"]


@pytest.mark.parametrize("poi", ["workstations: []\n", None])
def test_world_without_workstations_exits_2(tmp_path, poi):
    world = tmp_path / "empty.world"
    world.write_text(WORLD_SDF)
    if poi is not None:
        (tmp_path / "empty.yaml").write_text(poi)
    res = commander("Srobot1", "--world", str(world), *WALL)
    assert res.returncode == 2
    lines = res.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith("swarm-commander: error: --world: world empty has no workstations")


@pytest.mark.parametrize("text, expected", [
    ("waypoints: [loadr1]\n", "unknown workstation 'loadr1' (did you mean 'loader1'?)"),
    ("waypoint: [loader1]\n", "unknown key 'waypoint' (did you mean 'waypoints'?)"),
    ("waypoints: [{x: 1, y: 2}]\n", "missing key 'yaw'"),
    ("waypoints: [\n", "not valid YAML"),
])
def test_malformed_route_file_exits_2(world, tmp_path, text, expected):
    route = tmp_path / "bad_route.yaml"
    route.write_text(text)
    res = commander("Srobot1", "--world", str(world), "--route", str(route), *WALL)
    assert res.returncode == 2
    lines = res.stderr.splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(f"swarm-commander: error: {route}: ")
    assert expected in lines[0]


@pytest.mark.parametrize("args, expected", [
    (["3x"], "NS: '3x' is not a valid ROS namespace"),
    (["S1", "--loops", "-1"], "--loops: must be an integer >= 0, got '-1'"),
    (["S1", "--loops", "x"], "--loops: must be an integer >= 0, got 'x'"),
    (["S1", "--seed", "-2"], "--seed: must be an integer >= 0, got '-2'"),
    (["S1", "--wait-timeout", "0"], "--wait-timeout: must be a positive number"),
    (["S1", "--world", "no_such_world_xyz"], "--world: unknown world 'no_such_world_xyz'"),
    (["S1", "--ros-args", "-p", "nonsense"], "--ros-args: Couldn't parse parameter override"),
])
def test_bad_arguments_exit_2_with_one_line(args, expected):
    res = commander(*args)
    assert res.returncode == 2
    lines = res.stderr.splitlines()
    assert len(lines) == 1 and expected in lines[0], res.stderr


def test_uses_sim_time_by_default(context, ns, world):
    """Without --ros-args the node runs on /clock (absent here: every task takes 0.0 s)."""
    with running_fake_navigator(ns, context, drive_time=0.05):
        res = commander(ns, "--world", str(world), "--loops", "1")
    assert res.returncode == 0, res.stderr
    lines = res.stdout.splitlines()
    assert len(lines) == 4
    assert all(re.match(r"^\[\w+\] task \d: reached \w+ in 0\.0 s \(sim\)$", line)
               for line in lines[:3]), lines


def test_ctrl_c_prints_a_summary_and_exits_cleanly(context, ns, world):
    with running_fake_navigator(ns, context, drive_time=0.1):
        proc = subprocess.Popen(
            [sys.executable, "-m", "swarm_commander.cli", ns, "--world", str(world), *WALL],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        lines: queue.Queue[str] = queue.Queue()
        reader = threading.Thread(target=lambda: [lines.put(x) for x in proc.stdout],
                                  daemon=True)
        reader.start()
        try:
            first = lines.get(timeout=20.0)
            assert REACHED.match(first.rstrip("\n")), first
            proc.send_signal(signal.SIGINT)
            proc.wait(timeout=60.0)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
        # the process has ended: its stdout reaches EOF and the reader ends, however loaded the
        # machine (a 5 s join lost the summary line once, a CI run beside a 100-robot sweep)
        reader.join(timeout=120.0)
        assert not reader.is_alive()
        stderr = proc.stderr.read()
        proc.stdout.close()
        proc.stderr.close()
    out = []
    while not lines.empty():
        out.append(lines.get().rstrip("\n"))
    assert proc.returncode == 0, stderr
    assert re.match(rf"^\[{ns}\] summary: \d+ tasks: \d+ reached, 0 failed, 0 canceled"
                    r"(, 1 unfinished)? in \d+\.\d s \(wall\)$", out[-1]), out
    assert "Traceback" not in stderr


def test_runners_of_several_robots_share_one_executor(context, tmp_path):
    """Two robots' commanders in one process, driven by one executor's callbacks."""
    (tmp_path / "w.yaml").write_text(POI_YAML)
    stations = load_poi(tmp_path / "w.yaml").workstations
    names = [f"Tgrp{next(_COUNTER)}" for _ in range(2)]
    lines: list[str] = []
    navs, runners = [], []
    executor = SingleThreadedExecutor(context=context)
    with running_fake_navigator(names[0], context, drive_time=0.1) as fake_a, \
            running_fake_navigator(names[1], context, drive_time=0.1) as fake_b:
        try:
            for i, ns in enumerate(names):
                nav = BasicNavigator(node_name="commander", namespace=ns, context=context,
                                     parameter_overrides=[Parameter("use_sim_time", value=False)])
                stops = stops_from_workstations(stations)
                route = RandomRoute(stops, route_rng(0, ns)) if i == 0 else FixedRoute(stops)
                cfg = CommanderConfig(loops=2, wait_timeout=10.0)
                runners.append(CommanderRunner(nav, route, cfg, emit=lines.append))
                navs.append(nav)
                executor.add_node(nav)
            deadline = time.monotonic() + 20.0
            while not all(r.finished.done() for r in runners):
                assert time.monotonic() < deadline, lines
                executor.spin_once(timeout_sec=0.1)
        finally:
            executor.shutdown(timeout_sec=0)
            for nav in navs:
                nav.destroy_node()
    assert [r.finished.result() for r in runners] == [0, 0]
    assert [(r.tasks, r.reached) for r in runners] == [(6, 6), (6, 6)]
    for fake in (fake_a, fake_b):
        visited = [(x, y) for _, x, y in fake.goals]
        assert sorted(visited[:3]) == sorted(STATIONS.values())
        assert sorted(visited[3:]) == sorted(STATIONS.values())
    assert sum(line.startswith(f"[{names[1]}] task") for line in lines) == 6
    assert runners[0].summary().startswith(f"[{names[0]}] summary: 6 tasks: 6 reached")


def test_the_line_names_the_workstation_the_navigator_took_and_its_stop_is_skipped(context,
                                                                                   tmp_path):
    """The navigator takes loader2 when sent to loader1 (taken) and the pose (5, 5) when sent
    to unload: the lines name what was reached, and the route's next stop, loader2, where the
    robot now stands, is skipped (route: loader1, loader2, unload, twice)."""
    ns = f"Tswap{next(_COUNTER)}"
    (tmp_path / "w.yaml").write_text(POI_YAML)
    stops = stops_from_workstations(load_poi(tmp_path / "w.yaml").workstations)
    take = {STATIONS["loader1"]: (2.0, 1.0, 1.5708), STATIONS["unload"]: (5.0, 5.0, 0.0)}
    cfg = CommanderConfig(loops=2, wait_timeout=10.0)
    runner, fake, lines = _run_route(context, ns, FixedRoute(stops), cfg, drive_time=0.1,
                                     take_instead=take)
    assert runner.finished.result() == 0
    assert [(x, y) for _, x, y in fake.goals] == [STATIONS["loader1"], STATIONS["unload"]] * 2
    assert (runner.tasks, runner.reached, runner.skipped) == (4, 4, 2)
    tails = [re.sub(r" in \d+\.\d s \(wall\)", "", line.split(": ", 1)[1]) for line in lines]
    assert tails == ["reached loader2, sent to loader1 (taken)",
                     "reached (5.00, 5.00), sent to unload (taken)"] * 2


def _run_route(context, ns, route, cfg, **fake_args):
    """Run one CommanderRunner over ``route`` against a fake navigator until it finishes
    (20 s wall at most); returns (runner, the fake navigator, the lines)."""
    lines: list[str] = []
    executor = SingleThreadedExecutor(context=context)
    with running_fake_navigator(ns, context, **fake_args) as fake:
        nav = BasicNavigator(node_name="commander", namespace=ns, context=context,
                             parameter_overrides=[Parameter("use_sim_time", value=False)])
        runner = CommanderRunner(nav, route, cfg, emit=lines.append)
        executor.add_node(nav)
        try:
            deadline = time.monotonic() + 20.0
            while not runner.finished.done():
                assert time.monotonic() < deadline, lines
                executor.spin_once(timeout_sec=0.1)
        finally:
            executor.shutdown(timeout_sec=0)
            nav.destroy_node()
    return runner, fake, lines


def test_service_time_stamps_the_goal_after_an_arrival_that_much_later(context, tmp_path):
    """With a service time of 30 s, every goal after a workstation reached is stamped 30 s
    (simulated, the status's stamp) after the arrival; after an aborted goal the next goal is
    not delayed. Route: loader1, loader2, unload (x > 1.5 aborts), twice."""
    ns = f"Tsvc{next(_COUNTER)}"
    (tmp_path / "w.yaml").write_text(POI_YAML)
    stops = stops_from_workstations(load_poi(tmp_path / "w.yaml").workstations)
    cfg = CommanderConfig(loops=2, wait_timeout=10.0, service_time=30.0)
    runner, fake, _ = _run_route(context, ns, FixedRoute(stops), cfg, drive_time=0.1,
                                 abort_x=1.5, stamp_step_ns=1_000_000)  # 1 ms per status
    assert runner.finished.result() == 0
    assert (runner.tasks, runner.reached, runner.failed) == (6, 4, 2)
    stamps = [int(gid.replace(".", "")) for gid, _, _ in fake.goals]
    service = 30 * 10**9
    # loader1 and unload are reached, loader2 (x 2.0) aborts: goals 1, 3 and 4 follow an
    # arrival, goals 2 and 5 an aborted goal
    assert len(fake.ended) == 4
    for k, arrival in zip((1, 3, 4), fake.ended, strict=False):
        assert stamps[k] == arrival + service
    for k in (2, 5):  # no service: stamped with the status (1 ns after the last goal here)
        assert 0 < stamps[k] - stamps[k - 1] < 10**9


def test_the_runner_is_driven_by_the_navigators_events_not_its_idle_timer(context, tmp_path):
    """With an idle period of a minute, the runner still sends its first goal on the first
    status and every next one on the end of the last: the route of 4 stops is done in well under
    the idle period (its timer then fires only while something is due)."""
    ns = f"Tidle{next(_COUNTER)}"
    (tmp_path / "w.yaml").write_text(POI_YAML)
    stops = stops_from_workstations(load_poi(tmp_path / "w.yaml").workstations)
    lines: list[str] = []
    executor = SingleThreadedExecutor(context=context)
    with running_fake_navigator(ns, context, drive_time=0.1) as fake:
        nav = BasicNavigator(node_name="commander", namespace=ns, context=context,
                             parameter_overrides=[Parameter("use_sim_time", value=False)])
        cfg = CommanderConfig(loops=2, wait_timeout=30.0, idle_period=60.0)
        runner = CommanderRunner(nav, FixedRoute(stops[:2]), cfg, emit=lines.append)
        executor.add_node(nav)
        try:
            deadline = time.monotonic() + 30.0
            while not runner.finished.done():
                assert time.monotonic() < deadline, lines
                executor.spin_once(timeout_sec=0.1)
        finally:
            executor.shutdown(timeout_sec=0)
            nav.destroy_node()
    assert runner.finished.result() == 0
    assert (runner.tasks, runner.reached) == (4, 4)
    assert len(fake.goals) == 4


def test_the_wait_for_the_navigator_counts_from_the_first_spin_not_from_construction(
        context, tmp_path):
    """A group process makes all its commanders before it spins any (minutes at 500 robots):
    a runner made ``wait_timeout`` seconds before its executor spins still waits that long
    for its navigator, and drives its route."""
    ns = f"Tlate{next(_COUNTER)}"
    (tmp_path / "w.yaml").write_text(POI_YAML)
    stops = stops_from_workstations(load_poi(tmp_path / "w.yaml").workstations)
    lines: list[str] = []
    executor = SingleThreadedExecutor(context=context)
    nav = BasicNavigator(node_name="commander", namespace=ns, context=context,
                         parameter_overrides=[Parameter("use_sim_time", value=False)])
    cfg = CommanderConfig(loops=1, wait_timeout=5.0)
    runner = CommanderRunner(nav, FixedRoute(stops[:1]), cfg, emit=lines.append)
    time.sleep(6.0)  # longer than wait_timeout, before anything spins
    with running_fake_navigator(ns, context, drive_time=0.1) as fake:
        executor.add_node(nav)
        try:
            deadline = time.monotonic() + 30.0
            while not runner.finished.done():
                assert time.monotonic() < deadline, lines
                executor.spin_once(timeout_sec=0.1)
        finally:
            executor.shutdown(timeout_sec=0)
            nav.destroy_node()
    assert (runner.finished.result(), runner.error) == (0, None)
    assert (runner.tasks, runner.reached, len(fake.goals)) == (1, 1, 1)


def test_subprocesses_inherit_the_private_domain():
    assert os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "LOCALHOST"
    assert os.environ["ROS_DOMAIN_ID"] == os.environ["SWARM_WB_TEST_DOMAIN"]
