"""``swarm-plot`` on a synthetic recording (no ROS run): what it reads, what it draws, bad input.

The recording is built with :class:`swarm_record.mcap_format.McapRecording` from messages
serialized by ``rosbags`` (3 robots on known straight lines, one collision, two goals reached, one
HOLDING), so every figure is known in advance.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image
from rosbags.typesys import Stores, get_typestore

from swarm_common.events import COLLISION, CollisionEvent
from swarm_record import mcap_format as rec
from swarm_record import plot

T = get_typestore(Stores.ROS2_JAZZY).types
STORE = get_typestore(Stores.ROS2_JAZZY)
BIN = Path(sys.executable).parent
ROBOTS = ("Srobot1", "Srobot2", "Srobot3")
STEPS = 100  # ticks of 0.1 s
WORKSTATIONS = [{"name": "loader1", "x": -4.0, "y": -3.0, "yaw": 0.0, "holding": [[-4.0, -2.0]]},
                {"name": "loader2", "x": -4.0, "y": 3.0, "yaw": 0.0, "holding": [[-4.0, 2.0]]}]


def _time(ns):
    return T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9)


def _header(ns, frame):
    return T["std_msgs/msg/Header"](stamp=_time(ns), frame_id=frame)


def _odom(ns_time, x, y):
    g = {n: T[f"geometry_msgs/msg/{n}"] for n in (
        "PoseWithCovariance", "Pose", "Point", "Quaternion", "TwistWithCovariance", "Twist",
        "Vector3")}
    v3 = g["Vector3"](x=0.0, y=0.0, z=0.0)
    msg = T["nav_msgs/msg/Odometry"](
        header=_header(ns_time, "map"), child_frame_id="base_footprint",
        pose=g["PoseWithCovariance"](pose=g["Pose"](
            position=g["Point"](x=x, y=y, z=0.0),
            orientation=g["Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)), covariance=np.zeros(36)),
        twist=g["TwistWithCovariance"](twist=g["Twist"](linear=v3, angular=v3),
                                       covariance=np.zeros(36)))
    return bytes(STORE.serialize_cdr(msg, "nav_msgs/msg/Odometry"))


def _kv(values):
    return [T["diagnostic_msgs/msg/KeyValue"](key=k, value=str(v)) for k, v in values.items()]


def _status(name, message, values, hw=""):
    return T["diagnostic_msgs/msg/DiagnosticStatus"](level=0, name=name, message=message,
                                                     hardware_id=hw, values=_kv(values))


def _nav_status(state, goal, stamp_s):
    values = {"state": state, "goal_id": goal, "stamp": f"{int(stamp_s)}.{0:09d}"}
    return bytes(STORE.serialize_cdr(_status("n", state, values),
                                     "diagnostic_msgs/msg/DiagnosticStatus"))


def _map():
    info = T["nav_msgs/msg/MapMetaData"](
        map_load_time=_time(0), resolution=0.1, width=100, height=80,
        origin=T["geometry_msgs/msg/Pose"](
            position=T["geometry_msgs/msg/Point"](x=-5.0, y=-4.0, z=0.0),
            orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0)))
    grid = np.zeros((80, 100), dtype=np.int8)
    grid[0, :] = grid[-1, :] = grid[:, 0] = grid[:, -1] = 100
    msg = T["nav_msgs/msg/OccupancyGrid"](header=_header(0, "map"), info=info,
                                          data=grid.ravel())
    return bytes(STORE.serialize_cdr(msg, "nav_msgs/msg/OccupancyGrid"))


def make_recording(path: Path) -> None:
    """3 robots: robot i drives from (-3, 2 - 2 i) to (4, 2 - 2 i) in 10 s."""
    out = rec.McapRecording(path, chunk_size=8192)
    out.add_metadata(rec.META_NAME, rec.run_metadata(
        world="/x/worlds/test_floor.world", robot="turtlebot3_waffle", seed=0, robots=ROBOTS,
        workstations=WORKSTATIONS, rtf=0.0))
    latched = rec.qos_yaml([dict(history="keep_last", depth=1, reliability="reliable",
                                 durability="transient_local")])
    out.add_channel("/map", "nav_msgs/msg/OccupancyGrid", latched)
    out.write("/map", 0, _map())
    for ns in ROBOTS:
        out.add_channel(f"/{ns}/ground_truth", "nav_msgs/msg/Odometry", latched)
        out.add_channel(f"/{ns}/nav_status", "diagnostic_msgs/msg/DiagnosticStatus", latched)
    out.add_channel("/swarm/events", "diagnostic_msgs/msg/DiagnosticArray", latched)
    for k in range(1, STEPS + 1):
        t = k * 100_000_000
        for i, ns in enumerate(ROBOTS):
            out.write(f"/{ns}/ground_truth", t, _odom(t, -3.0 + 7.0 * k / STEPS, 2.0 - 2.0 * i))
    for ns, state, goal, s in (("Srobot1", "SUCCEEDED", "1.000000000", 4),
                               ("Srobot1", "SUCCEEDED", "1.000000000", 5),  # repeat: one task
                               ("Srobot2", "HOLDING", "2.000000000", 6),
                               ("Srobot2", "SUCCEEDED", "2.000000000", 8)):
        out.write(f"/{ns}/nav_status", s * 10**9, _nav_status(state, goal, s))
    events = T["diagnostic_msgs/msg/DiagnosticArray"](header=_header(5 * 10**9, ""), status=[
        _status(COLLISION, "robot-wall collision",
                CollisionEvent("Srobot3", 0.5, -2.0, 5.0, other="wall").encode())])
    out.write("/swarm/events", 5 * 10**9,
              bytes(STORE.serialize_cdr(events, "diagnostic_msgs/msg/DiagnosticArray")))
    out.close()


def test_read_run_gives_the_recorded_figures(tmp_path):
    path = tmp_path / "r.mcap"
    make_recording(path)
    trace = plot.read_run(path)
    assert trace.robots == list(ROBOTS) and not trace.truncated
    assert trace.world == "test_floor"
    for i, ns in enumerate(ROBOTS):
        xy = trace.paths[ns]
        assert xy.shape == (STEPS, 3)
        assert xy[0].tolist() == pytest.approx([0.1, -3.0 + 0.07, 2.0 - 2.0 * i])
        assert xy[-1].tolist() == pytest.approx([10.0, 4.0, 2.0 - 2.0 * i])
    assert trace.tasks == [4.0, 8.0]
    assert trace.collisions.tolist() == [[0.5, -2.0]]
    assert trace.holding_starts["Srobot2"].ravel().tolist() == pytest.approx([1.2, 0.0])
    assert trace.grid.shape == (80, 100) and trace.origin == (-5.0, -4.0)
    assert trace.workstations == WORKSTATIONS
    assert trace.duration_s == pytest.approx(10.0)


def _colour_pixels(png: Path, rgb, tol=12) -> int:
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    target = np.asarray([round(c * 255) for c in rgb])
    return int((np.abs(img - target).max(axis=2) <= tol).sum())


def test_swarm_plot_draws_every_robot_in_its_colour(tmp_path):
    path = tmp_path / "r.mcap"
    make_recording(path)
    out = tmp_path / "out.png"
    res = subprocess.run([str(BIN / "swarm-plot"), str(path), "-o", str(out)],
                         capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert "3 robots, 10 s simulated, 2 tasks, 1 collisions" in res.stdout
    with Image.open(out) as img:
        assert img.size == (round(plot.FIG_SIZE[0] * plot.DPI), round(plot.FIG_SIZE[1] * plot.DPI))
    # Each robot's 7 m line is ~ 7 / 15 of the axes' width long and 1.6 pt wide: hundreds of
    # pixels of its own colour.
    for rgb in plot.robot_colors(len(ROBOTS)):
        assert _colour_pixels(out, rgb) > 300, rgb
    assert _colour_pixels(out, (1.0, 0.0, 0.0)) > 30  # the collision's red cross
    tasks = tmp_path / "out-tasks.png"
    with Image.open(tasks) as img:
        assert img.size == (960, 540)
    assert _colour_pixels(tasks, plot.robot_colors(1)[0]) > 200  # the tab:blue curve


def test_swarm_plot_reads_a_cut_off_recording(tmp_path):
    """A file cut in the middle of a chunk, as by a SIGKILL during a write."""
    whole, path = tmp_path / "whole.mcap", tmp_path / "cut.mcap"
    make_recording(whole)
    data = whole.read_bytes()
    path.write_bytes(data[: len(data) // 2])
    trace = plot.read_run(path)
    assert trace.truncated
    n = len(trace.paths["Srobot1"])
    assert 20 < n < STEPS  # the complete chunks only
    assert np.allclose(np.diff(trace.paths["Srobot1"][:, 0]), 0.1)


def test_find_recording_in_a_run_dir(tmp_path):
    run = tmp_path / "run"
    run.mkdir()
    with pytest.raises(plot.InputError, match="no recording"):
        plot.find_recording(run)
    (run / "a.mcap").write_bytes(b"")
    assert plot.find_recording(run) == run / "a.mcap"
    (run / "b.mcap").write_bytes(b"")
    with pytest.raises(plot.InputError, match="2 .mcap files"):
        plot.find_recording(run)
    (run / "recording.mcap").write_bytes(b"")
    assert plot.find_recording(run) == run / "recording.mcap"
    elsewhere = tmp_path / "elsewhere.mcap"
    elsewhere.write_bytes(b"")
    (run / "metrics.json").write_text(json.dumps({"recording": str(elsewhere)}))
    assert plot.find_recording(run) == elsewhere


def test_output_paths():
    rec_path = Path("/r/run.mcap")
    assert plot.output_paths(rec_path, None) == (Path("/r/run-trajectories.png"),
                                                 Path("/r/run-tasks.png"))
    assert plot.output_paths(rec_path, Path("/o/x.png")) == (Path("/o/x.png"),
                                                             Path("/o/x-tasks.png"))


@pytest.mark.parametrize(("args", "flag"), [
    (["/nonexistent_dir_xyz/run.mcap"], "RUN"),
    (["{tmp}/notes.txt"], "RUN"),
    (["{tmp}/fake.mcap"], "RUN"),
    (["{tmp}"], "RUN"),
    (["{tmp}/r.mcap", "-o", "{tmp}/out.jpg"], "--output"),
    (["{tmp}/r.mcap", "-o", "/nonexistent_dir_xyz/out.png"], "--output"),
    (["{tmp}/r.mcap", "--bogus"], "--bogus"),
    ([], "RUN_DIR|FILE.mcap"),
])
def test_bad_input_exits_2_with_one_line(args, flag, tmp_path):
    (tmp_path / "notes.txt").write_text("x")
    (tmp_path / "fake.mcap").write_text("not an mcap file")
    make_recording(tmp_path / "r.mcap")
    (tmp_path / "sub").mkdir()
    argv = [a.format(tmp=tmp_path / "sub" if a == "{tmp}" else tmp_path) for a in args]
    res = subprocess.run([str(BIN / "swarm-plot"), *argv], capture_output=True, text=True,
                         timeout=60)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2, res.stderr
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("swarm-plot: error: ") and flag in lines[0], lines[0]


def test_help_names_what_a_run_dir_holds():
    res = subprocess.run([str(BIN / "swarm-plot"), "--help"], capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 0
    assert "RUN/recording.mcap" in res.stdout and "metrics.json" in res.stdout


def test_core_of_plot_needs_no_ros():
    code = ("import sys; import swarm_record.plot, swarm_record.mcap_format; "
            "sys.exit(any(m.startswith('rclpy') for m in sys.modules))")
    assert subprocess.run([sys.executable, "-c", code], timeout=60).returncode == 0
    assert math.isfinite(plot.DPI)
