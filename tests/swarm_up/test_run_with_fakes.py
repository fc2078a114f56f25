"""``swarm-up`` end to end against stand-in simulator/navigator/commander processes.

The stand-ins (written to a temporary ``bin/`` put first on ``PATH``) speak the real ROS
interfaces of ``docs/ARCHITECTURE.md``: the fake simulator publishes ``/clock`` and spawn and
collision events on ``/swarm/events`` and writes ``--summary``; each fake navigator reads its
params file through rcl, checks it, and publishes ``/<ns>/nav_status`` (IDLE, DRIVING,
SUCCEEDED).  So this tests the orchestration, the metrics node and the metrics file, not
navigation.
"""

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from swarm_up import shm

pytestmark = [pytest.mark.e2e, pytest.mark.node]

FAKE_SIM = r'''
import argparse, json, os, sys, time
ap = argparse.ArgumentParser()
for flag in ("--world", "--robot", "--name-prefix", "--map", "--summary"):
    ap.add_argument(flag)
ap.add_argument("--swarm-size", type=int)
ap.add_argument("--seed", type=int)
ap.add_argument("--wait-for", type=int)
ap.add_argument("--rtf", type=float)
ap.add_argument("--duration", type=float)
ap.add_argument("--gui", action="store_true")
a = ap.parse_args()
if os.environ.get("FAKE_SIM_BAD_INPUT"):
    print("swarm-sim: error: --swarm-size: 3 robots do not fit the spawn area; 2 fit",
          file=sys.stderr)
    sys.exit(2)
import rclpy
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions
from rosgraph_msgs.msg import Clock
rclpy.init(signal_handler_options=SignalHandlerOptions.NO)  # Ctrl-C: write the summary
node = rclpy.create_node("swarm_sim")
events = node.create_publisher(DiagnosticArray, "/swarm/events",  # as the simulator's writer
                               QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE,
                                          durability=DurabilityPolicy.TRANSIENT_LOCAL))
clock = node.create_publisher(Clock, "/clock", 1)
names = [f"{a.name_prefix}{i}" for i in range(1, a.swarm_size + 1)]
t_wall0 = time.monotonic()

def event(kind, **values):
    st = DiagnosticStatus(name=kind, message=kind,
                          values=[KeyValue(key=k, value=str(v)) for k, v in values.items()])
    events.publish(DiagnosticArray(status=[st]))

sim_t, dt, ticks = 0.0, 0.1, 0
crash_after = float(os.environ.get("FAKE_SIM_CRASH_AFTER", "inf"))
try:
    while events.get_subscription_count() == 0 and time.monotonic() - t_wall0 < 10:
        time.sleep(0.05)
    for i, n in enumerate(names, start=1):
        event("spawn", robot=n, x=i, y=0, t=0)
        print(f"spawned {i} robots", flush=True)
    event("collision", robot=names[0], other="wall::link::box", x=1, y=1, t=0.5)
    while a.duration is None or sim_t < a.duration:
        time.sleep(dt)
        sim_t += dt
        ticks += 1
        clock.publish(Clock(clock=Time(sec=int(sim_t), nanosec=int(sim_t % 1 * 1e9))))
        if time.monotonic() - t_wall0 > crash_after:
            os._exit(3)
except KeyboardInterrupt:
    pass
summary = {"ticks": ticks, "sim_time_s": sim_t, "wall_time_s": time.monotonic() - t_wall0,
           "late_ticks": 0, "collisions": {"robot_robot": 0, "robot_wall": 1},
           "min_separation_m": 0.8,
           "per_robot": {n: {"distance_m": 1.5, "collisions": int(n == names[0]),
                             "late_ticks": 0} for n in names}}
with open(a.summary, "w") as fh:
    json.dump(summary, fh)
node.destroy_node()
rclpy.try_shutdown()
'''

FAKE_NAV = r'''
import os, sys, time
if os.environ.get("FAKE_NAV_CRASH"):
    sys.exit(1)
import rclpy
from diagnostic_msgs.msg import DiagnosticStatus, KeyValue
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
rclpy.init(args=sys.argv)
node = rclpy.create_node("navigator", automatically_declare_parameters_from_overrides=True)
ns = node.get_namespace().strip("/")
assert node.get_parameter("robot_name").value == ns, "params file not for this namespace"
assert node.get_parameter("use_sim_time").value is True
qos = QoSProfile(depth=1, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.TRANSIENT_LOCAL)
pub = node.create_publisher(DiagnosticStatus, f"/{ns}/nav_status", qos)

def status(state, goal="", nav_t="0.0"):
    vals = {"state": state, "goal_id": goal, "navigation_time_s": nav_t,
            "holding_time_s": "0.5" if goal else "0.0", "reason": ""}
    pub.publish(DiagnosticStatus(name=f"{ns}/navigator", hardware_id=ns, message=state,
                                 values=[KeyValue(key=k, value=v) for k, v in vals.items()]))

t0 = time.monotonic()
try:
    while True:
        age = time.monotonic() - t0
        if age < 1.0:
            status("IDLE")
        elif age < 1.5:
            status("DRIVING", "7.000000000", "1.0")
        else:
            status("SUCCEEDED", "7.000000000", "2.5")
        time.sleep(0.25)
except KeyboardInterrupt:
    pass
node.destroy_node()
rclpy.try_shutdown()
'''

FAKE_COMMANDER = r'''
import os, signal, sys, time
signal.signal(signal.SIGINT, lambda *a: sys.exit(0))
if sys.argv[1] == os.environ.get("FAKE_CMD_EXIT_2"):  # as a commander that gives up
    time.sleep(1.0)
    print(f"swarm-commander: error: {sys.argv[1]}: no navigator answered", file=sys.stderr)
    sys.exit(2)
time.sleep(1000)
'''

FAKE_COORDINATOR = r'''
import signal, sys, time
signal.signal(signal.SIGINT, lambda *a: sys.exit(0))
time.sleep(1000)
'''

TEMPLATE = "navigator:\n  ros__parameters:\n    control_period: 0.1  # [s]\n"
MAP_YAML = ("image: m.pgm\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
            "occupied_thresh: 0.65\nfree_thresh: 0.25\nmode: trinary\n")
WORLD = ("<?xml version='1.0'?><sdf version='1.6'><world name='w'><model name='box'>"
         "<static>true</static><pose>1 1 0.5 0 0 0</pose><link name='l'><collision name='c'>"
         "<geometry><box><size>1 1 1</size></box></geometry></collision></link></model>"
         "</world></sdf>")
POI = "workstations:\n  - {name: station1, x: 0.5, y: 0.5, yaw: 0.0}\n"


@pytest.fixture
def setup(tmp_path):
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir()
    for name, body in (("swarm-sim", FAKE_SIM), ("swarm-nav", FAKE_NAV),
                       ("swarm-commander", FAKE_COMMANDER),
                       ("swarm-coordinator", FAKE_COORDINATOR)):
        path = bin_dir / name
        path.write_text(f"#!{sys.executable}\n{body}")
        path.chmod(0o755)
    (tmp_path / "navigator.yaml").write_text(TEMPLATE)
    (tmp_path / "m.yaml").write_text(MAP_YAML)
    (tmp_path / "m.pgm").write_bytes(b"P5\n20 20\n255\n" + bytes([254]) * 400)
    (tmp_path / "w.world").write_text(WORLD)
    (tmp_path / "w.yaml").write_text(POI)  # --commanders needs a workstation to visit
    env = dict(os.environ, PATH=f"{bin_dir}{os.pathsep}{os.environ.get('PATH', '')}")
    return tmp_path, env


def _argv(tmp_path, *extra):
    return [sys.executable, "-m", "swarm_up.cli", "--swarm-size", "2",
            "--world", str(tmp_path / "w.world"), "--map", str(tmp_path / "m.yaml"),
            "--nav-params", str(tmp_path / "navigator.yaml"),
            "--run-dir", str(tmp_path / "run"), "--metrics", str(tmp_path / "metrics.json"),
            "--ready-timeout", "30", "--processes", "per-robot", *extra]  # the fakes: swarm-nav


def _own_segments(procs) -> set[str]:
    """The Fast DDS participant segments (``fastrtps_<16 hex>`` groups, :func:`shm.group_key`)
    that ``procs`` have open or mmapped now. Port files (``fastrtps_port<N>``) are left out:
    every participant on the machine shares them by number, so one left behind may be anyone's
    (a swarm-up beside this test)."""
    found = set()
    for proc in procs:
        try:
            paths = [f.path for f in proc.open_files()] + [m.path for m in proc.memory_maps()]
        except (psutil.NoSuchProcess, psutil.AccessDenied):
            continue
        found |= {shm.group_key(Path(path).name) for path in paths
                  if path.startswith("/dev/shm/") and shm.is_fastdds_name(Path(path).name)}
    return {g for g in found if not g.startswith("fastrtps_port")}


def _descendants_gone(pids, timeout=2.0):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        alive = [p for p in pids if psutil.pid_exists(p)
                 and psutil.Process(p).status() != psutil.STATUS_ZOMBIE]
        if not alive:
            return True
        time.sleep(0.05)
    return False


def _start(argv, env, cwd):
    return subprocess.Popen(argv, env=env, cwd=cwd, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _finish(proc, timeout):
    try:
        out, err = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        out, err = proc.communicate()
        pytest.fail(f"swarm-up did not end in time\n{out}\n{err}")
    return out, err


def test_run_to_duration_writes_metrics(setup):
    tmp_path, env = setup
    proc = _start(_argv(tmp_path, "--duration", "5", "--commanders"), env, tmp_path)
    out, err = _finish(proc, 40)
    assert proc.returncode == 0, out + err
    assert "navigators ready: 2/2" in out
    assert "swarm-up summary" in out
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert json.loads((tmp_path / "run" / "metrics.json").read_text()) == m
    assert m["robots"] == 2 and m["world"] == "w" and m["ended_by"] == "duration"
    assert m["goals_reached"] == 2 and m["goals_aborted"] == 0
    assert m["mean_time_to_goal_s"] == pytest.approx(2.5)
    assert m["holding_time_s"] == pytest.approx(1.0)
    assert m["sim_time_s"] == pytest.approx(5.0, abs=0.15)
    assert m["collisions"] == {"robot_robot": 0, "robot_wall": 1}
    assert m["spawn_to_ready_s"] is not None and m["spawn_to_ready_s"] < 30
    assert m["restarts"] == 0
    assert m["peak_rss_mb_per_robot"] > 5 and m["cpu_percent"] > 0
    assert set(m["per_robot"]) == {"Srobot1", "Srobot2"}
    assert m["per_robot"]["Srobot1"]["collisions"] == 1
    logs = sorted(p.name for p in (tmp_path / "run" / "logs").iterdir())
    assert logs == ["cmd_Srobot1.log", "cmd_Srobot2.log", "nav_Srobot1.log", "nav_Srobot2.log",
                    "sim.log"]
    assert "spawned 2 robots" in (tmp_path / "run" / "logs" / "sim.log").read_text()


def test_killed_navigator_restarts_and_ctrl_c_stops_all(setup):
    tmp_path, env = setup
    shm_before = shm.snapshot()
    proc = _start(_argv(tmp_path), env, tmp_path)
    try:
        me = psutil.Process(proc.pid)
        navs = []
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline and len(navs) < 2:
            navs = [c for c in me.children() if "swarm-nav" in " ".join(c.cmdline())]
            time.sleep(0.2)
        assert len(navs) == 2
        log = tmp_path / "run" / "logs" / "nav_Srobot1.log"
        victim = next(c for c in navs if "__ns:=/Srobot1" in c.cmdline())
        time.sleep(2.0)
        victims = _own_segments([victim])
        ours = victims | _own_segments([me, *me.children(recursive=True)])
        victim.kill()
        t_kill = time.monotonic()
        while time.monotonic() - t_kill < 3 and "restart 1 of" not in log.read_text():
            time.sleep(0.05)
        assert time.monotonic() - t_kill < 2.0, "not restarted within 2 s"
        time.sleep(1.0)
        children = [c.pid for c in me.children(recursive=True)]
        assert len(children) >= 3
        ours |= _own_segments([me, *me.children(recursive=True)])
    finally:
        t_int = time.monotonic()
        proc.send_signal(signal.SIGINT)
        out, err = _finish(proc, 10)
    assert time.monotonic() - t_int < 6.0
    assert proc.returncode == 0, out + err
    assert _descendants_gone(children)
    assert "restarted" in err
    # The killed navigator's Fast DDS files are gone, and no other segment of this run's
    # processes is left: swarm-up removed them ("removed N stale shared-memory files"), or the
    # restarted participant reclaimed them first (Fast DDS does). Only this run's own segments
    # count: other programs on the machine leave files in /dev/shm as well.
    assert victims, "the killed navigator had no Fast DDS segment: nothing to check"
    left = [f for f in shm.stale_files(shm_before, min_age_s=0.0)
            if shm.group_key(f.name) in ours]
    assert left == [], out
    m = json.loads((tmp_path / "metrics.json").read_text())
    assert m["restarts"] == 1 and m["ended_by"] == "interrupted"
    assert m["sim_time_s"] is not None  # the fake simulator wrote its summary on SIGINT


def test_simulator_crash_is_fatal(setup):
    tmp_path, env = setup
    env["FAKE_SIM_CRASH_AFTER"] = "2.0"
    proc = _start(_argv(tmp_path), env, tmp_path)
    out, err = _finish(proc, 30)
    assert proc.returncode == 1
    log = tmp_path / "run" / "logs" / "sim.log"
    assert f"swarm-up: error: simulator exited with code 3; logs: {log}" in err
    assert "Traceback" not in err


def test_simulator_bad_input_is_relayed(setup):
    tmp_path, env = setup
    env["FAKE_SIM_BAD_INPUT"] = "1"
    proc = _start(_argv(tmp_path), env, tmp_path)
    out, err = _finish(proc, 30)
    assert proc.returncode == 2
    errors = [ln for ln in err.splitlines() if "error:" in ln]
    assert len(errors) == 1 and "2 fit" in errors[0] and "swarm-sim: error" not in errors[0]


def test_navigators_that_keep_crashing_fail_the_run(setup):
    tmp_path, env = setup
    env["FAKE_NAV_CRASH"] = "1"
    proc = _start(_argv(tmp_path), env, tmp_path)
    out, err = _finish(proc, 30)
    assert proc.returncode == 1
    assert "keeps crashing" in err
    assert f"every navigator process exited (nav_Srobot1: code 1); logs: {tmp_path}" in err
    assert "Traceback" not in err


@pytest.mark.parametrize("coordination", ["centralized", "decentralized"])
def test_a_commander_that_gives_up_ends_a_centralized_run_only(setup, coordination):
    """Centralized, the coordinator would wait for that robot for good: the run ends at once
    with the error; decentralized, its robot idles and the run goes on to its duration."""
    tmp_path, env = setup
    env["FAKE_CMD_EXIT_2"] = "Srobot2"
    proc = _start(_argv(tmp_path, "--duration", "8", "--commanders", "--coordination",
                        coordination), env, tmp_path)
    out, err = _finish(proc, 60)
    log = tmp_path / "run" / "logs" / "cmd_Srobot2.log"
    m = json.loads((tmp_path / "metrics.json").read_text())
    if coordination == "centralized":
        assert proc.returncode == 1, out + err
        assert err.strip().splitlines()[-1] == (
            "swarm-up: error: cmd_Srobot2 exited with code 2 and is not restarted: the "
            f"coordinator would wait for its robot for good; logs: {log}"), err
        assert m["ended_by"] == "commander failed"
    else:
        assert proc.returncode == 0, out + err
        assert f"cmd_Srobot2 exited with code 2; not restarted; logs: {log}" in err
        assert m["ended_by"] == "duration"
    assert "Traceback" not in err


def test_missing_template_is_a_runtime_failure(setup):
    tmp_path, env = setup
    argv = _argv(tmp_path)
    argv[argv.index("--nav-params") + 1] = str(tmp_path / "nope.yaml")
    res = subprocess.run(argv, env=env, cwd=tmp_path, capture_output=True, text=True, timeout=30)
    assert res.returncode == 2 and "--nav-params" in res.stderr
