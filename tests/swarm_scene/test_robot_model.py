"""swarm_scene.robot_model: URDF/xacro extraction against the seed facts, fallbacks, bad input."""

from __future__ import annotations

import logging
import math
import shutil
from pathlib import Path

import numpy as np
import pytest

from swarm_common.errors import InputError
from swarm_scene.robot_model import (
    DEFAULT_LIMITS,
    LDS01_DEFAULTS,
    RobotLimits,
    clear_robot_cache,
    load_limits,
    load_robot,
    resolve_robot,
    robot_names,
)

DATA = Path(__file__).resolve().parents[1] / "data"
LOGGER = "swarm_scene.robot_model"


@pytest.fixture(autouse=True)
def _fresh_cache():
    clear_robot_cache()
    yield
    clear_robot_cache()


def _warnings(caplog, word: str | None = None) -> list[str]:
    return [r.getMessage() for r in caplog.records
            if r.name == LOGGER and r.levelno == logging.WARNING
            and (word is None or word in r.getMessage())]


def _box(xmin, xmax, ymin, ymax) -> set[tuple[float, float]]:
    return {(xmin, ymin), (xmax, ymin), (xmax, ymax), (xmin, ymax)}


def _corners(footprint) -> set[tuple[float, float]]:
    return {(round(float(x), 6), round(float(y), 6)) for x, y in footprint}


def _signed_area(poly) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


# ------------------------------------------------------------------------------------------
# The bundled robots against seed_facts.md "Robots"

# name: (wheel sep, wheel radius, box sx, sy, centre x, base height above floor,
#        lidar frame, samples, angle_min, angle_max, range_min, range_max, rate, noise,
#        lidar x, lidar z above floor, limits (max_vel_x, max_vel_theta, acc x, acc theta))
SEED = {
    "turtlebot3_waffle": dict(
        sep=0.287, wheel_r=0.033, size=(0.266, 0.266), cx=-0.064, height=0.010 + 0.094,
        frame="base_scan", samples=360, angles=(0.0, 6.28319), ranges=(0.12, 3.5), rate=5.0,
        noise=0.01, lidar_x=-0.064, lidar_z=0.010 + 0.122, limits=(0.26, 1.82, 2.5, 3.2),
    ),
    "turtlebot3_burger": dict(
        sep=0.160, wheel_r=0.033, size=(0.140, 0.140), cx=-0.032, height=0.010 + 0.143,
        frame="base_scan", samples=360, angles=(0.0, 6.28319), ranges=(0.12, 3.5), rate=5.0,
        noise=0.01, lidar_x=-0.032, lidar_z=0.010 + 0.172, limits=(0.22, 2.84, 2.5, 3.2),
    ),
    "linorobot2_2wd": dict(
        sep=0.26, wheel_r=0.045, size=(0.24, 0.275), cx=0.0, height=0.068 + 0.05,
        frame="laser", samples=360, angles=(-math.pi, math.pi), ranges=(0.08, 12.0), rate=10.0,
        noise=0.01, lidar_x=0.0, lidar_z=0.068 + 0.1, limits=(0.4, 1.8, 2.5, 3.2),
    ),
}


def test_bundled_robot_names():
    assert robot_names() == sorted(SEED)


@pytest.mark.parametrize("name", sorted(SEED))
def test_bundled_robot_drive_and_footprint(name):
    fact = SEED[name]
    robot = load_robot(name)
    assert robot.name == name
    assert robot.source.name == f"{name}.urdf.xacro"
    assert robot.wheel_separation == pytest.approx(fact["sep"], abs=1e-9)
    assert robot.wheel_radius == pytest.approx(fact["wheel_r"], abs=1e-9)
    sx, sy = fact["size"]
    cx = fact["cx"]
    assert robot.footprint.shape == (4, 2)
    expected = _box(round(cx - sx / 2, 6), round(cx + sx / 2, 6), -sy / 2, sy / 2)
    assert _corners(robot.footprint) == expected
    assert _signed_area(robot.footprint) == pytest.approx(sx * sy)  # counter-clockwise
    far_x = max(abs(cx - sx / 2), abs(cx + sx / 2))
    assert robot.radius == pytest.approx(math.hypot(far_x, sy / 2))
    assert robot.height == pytest.approx(fact["height"])


def test_waffle_radius_is_the_circumscribed_circle_of_the_offset_box():
    # box x in [-0.197, 0.069], y in [-0.133, 0.133]: the rear corners are the farthest
    assert load_robot("turtlebot3_waffle").radius == pytest.approx(math.hypot(0.197, 0.133))


@pytest.mark.parametrize("name", sorted(SEED))
def test_bundled_robot_lidar(name, caplog):
    fact = SEED[name]
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        lidar = load_robot(name).lidar
    assert not _warnings(caplog, "lidar")  # the sensor block is there: no fallback
    assert lidar.frame == fact["frame"]
    assert lidar.samples == fact["samples"]
    assert (lidar.angle_min, lidar.angle_max) == pytest.approx(fact["angles"], abs=1e-5)
    assert (lidar.range_min, lidar.range_max) == pytest.approx(fact["ranges"])
    assert lidar.rate_hz == pytest.approx(fact["rate"])
    assert lidar.noise_stddev == pytest.approx(fact["noise"])
    assert lidar.pose.shape == (3,)
    assert lidar.pose == pytest.approx([fact["lidar_x"], 0.0, 0.0], abs=1e-9)
    assert lidar.z == pytest.approx(fact["lidar_z"])


@pytest.mark.parametrize("name", sorted(SEED))
def test_bundled_robot_limits(name):
    limits = load_robot(name).limits
    max_v, max_w, acc_v, acc_w = SEED[name]["limits"]
    assert limits == RobotLimits(max_vel_x=max_v, min_vel_x=-max_v, max_vel_theta=max_w,
                                 acc_lim_x=acc_v, acc_lim_theta=acc_w)


def test_waffle_limits_are_the_robot_not_the_navigator_limits():
    # nav2's TurtleBot3 controller turns at <= 1.0 rad/s; the robot itself can do 1.82 rad/s
    assert load_robot("turtlebot3_waffle").limits.max_vel_theta == pytest.approx(1.82)
    assert DEFAULT_LIMITS == load_robot("turtlebot3_waffle").limits


def test_unresolvable_package_meshes_warn_once_and_go_on(caplog):
    # a caller that would draw the meshes (a GUI) is warned, once
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        robot = load_robot("turtlebot3_waffle", need_meshes=True)
        again = load_robot("turtlebot3_waffle", need_meshes=True)
    mesh = _warnings(caplog, "mesh")
    assert len(mesh) == 1
    assert "robots/turtlebot3_waffle.urdf.xacro" in mesh[0]
    assert "package://turtlebot3_description" in mesh[0]
    assert "5 mesh file(s)" in mesh[0]
    assert robot.wheel_separation == pytest.approx(0.287)
    assert again is robot


@pytest.mark.parametrize("name", sorted(SEED))
def test_headless_load_says_nothing_about_meshes_above_debug(name, caplog):
    """Item 6 of issue 7: a newcomer's headless run shows no warning about meshes."""
    with caplog.at_level(logging.DEBUG, logger=LOGGER):
        first = load_robot(name)
        load_robot(name)
        load_robot(name, need_meshes=False)
    assert [r for r in caplog.records if r.name == LOGGER and r.levelno > logging.DEBUG] == []
    debug = [r.getMessage() for r in caplog.records
             if r.name == LOGGER and r.levelno == logging.DEBUG and "mesh" in r.getMessage()]
    assert len(debug) == (1 if name.startswith("turtlebot3") else 0)  # once, when there are any
    # the model is the same whether or not the meshes are needed
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        gui = load_robot(name, need_meshes=True)
        load_robot(name, need_meshes=True)
    assert gui is first
    assert len(_warnings(caplog, "mesh")) == (1 if name.startswith("turtlebot3") else 0)


def test_robot_by_path_equals_robot_by_name(repo_root, caplog):
    path = repo_root / "robots" / "turtlebot3_burger.urdf.xacro"
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        by_path = load_robot(str(path))
    by_name = load_robot("turtlebot3_burger")
    assert by_path.limits == by_name.limits  # params/robots/<stem>.yaml, no default warning
    assert not _warnings(caplog, "limits")
    assert np.array_equal(by_path.footprint, by_name.footprint)
    assert by_path.lidar.frame == by_name.lidar.frame


def test_xacro_prefix_arg_renames_frames():
    robot = load_robot("turtlebot3_waffle", xacro_args={"prefix": "Srobot1/"})
    assert robot.lidar.frame == "Srobot1/base_scan"
    assert robot.wheel_separation == pytest.approx(0.287)
    assert robot.lidar.z == pytest.approx(0.132)


def test_load_is_cached_and_read_only():
    first = load_robot("turtlebot3_waffle")
    assert load_robot("turtlebot3_waffle") is first
    with pytest.raises(ValueError):
        first.footprint[0, 0] = 1.0
    with pytest.raises(ValueError):
        first.lidar.pose[0] = 1.0
    assert {first: 1}[load_robot("turtlebot3_waffle")] == 1  # hashable: can key a cache


# ------------------------------------------------------------------------------------------
# Fixtures: xacro args, no sensor block, no base_footprint, cylinder base


def test_xacro_args_and_properties(caplog):
    path = DATA / "robot_args.urdf.xacro"
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        robot = load_robot(path)
    # no robot_args.yaml beside it and none in params/robots: waffle defaults, one warning
    assert robot.limits == DEFAULT_LIMITS
    assert len(_warnings(caplog)) == 1
    assert "no limits file" in _warnings(caplog)[0]
    assert "tests/data/robot_args.urdf.xacro" in _warnings(caplog)[0]
    assert robot.wheel_separation == pytest.approx(0.30)
    assert robot.lidar.samples == 180

    other = load_robot(path, xacro_args={"wheel_separation": "0.42", "samples": "90",
                                         "prefix": "r7_"})
    assert other.wheel_separation == pytest.approx(0.42)
    assert other.lidar.samples == 90
    assert other.lidar.frame == "r7_base_scan"


def test_urdf_declaring_the_xacro_namespace_is_processed(tmp_path):
    # as ROBOTIS' turtlebot3_waffle.urdf: a .urdf with xacro:arg namespace and ${namespace} names
    text = (DATA / "robot_args.urdf.xacro").read_text()
    path = _write(tmp_path, "tb3_style.urdf", text)
    robot = load_robot(path, xacro_args={"prefix": "tb3_0/"})
    assert robot.lidar.frame == "tb3_0/base_scan"
    assert robot.wheel_separation == pytest.approx(0.30)


def test_cylinder_base_is_a_16gon_and_floor_comes_from_the_wheels():
    robot = load_robot(DATA / "robot_args.urdf.xacro")
    assert robot.footprint.shape == (16, 2)
    assert np.hypot(robot.footprint[:, 0], robot.footprint[:, 1]) == pytest.approx(0.2)
    assert robot.radius == pytest.approx(0.2)
    # no base_footprint: floor = wheel centre (z -0.01) - radius 0.04 = -0.05 in base_link;
    # base cylinder top at 0.04 + 0.05 = 0.09 in base_link
    assert robot.height == pytest.approx(0.14)
    assert robot.wheel_radius == pytest.approx(0.04)


def test_sensor_pose_is_composed_with_the_link_pose():
    lidar = load_robot(DATA / "robot_args.urdf.xacro").lidar
    assert lidar.pose == pytest.approx([0.05 + 0.01, 0.0, math.pi / 2])
    assert lidar.z == pytest.approx(0.05 + 0.12 + 0.02)
    assert (lidar.angle_min, lidar.angle_max) == pytest.approx((-math.pi / 2, math.pi / 2))
    assert (lidar.range_min, lidar.range_max, lidar.rate_hz) == pytest.approx((0.05, 6.0, 20.0))
    assert lidar.noise_stddev == 0.0  # no <noise>: Gazebo adds none


def test_no_sensor_block_falls_back_to_params_lidar_block_with_one_warning(caplog):
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        robot = load_robot(DATA / "robot_no_sensor.urdf", need_meshes=True)
    lidar_warnings = _warnings(caplog, "lidar")
    assert len(lidar_warnings) == 1
    assert "tests/data/robot_no_sensor.urdf" in lidar_warnings[0]
    assert "'laser'" in lidar_warnings[0]
    assert len(_warnings(caplog, "mesh")) == 1  # its package:// meshes
    assert len(_warnings(caplog)) == 2
    lidar = robot.lidar
    assert lidar.frame == "laser"
    assert lidar.samples == 720  # from robot_no_sensor.yaml
    assert (lidar.angle_min, lidar.angle_max) == (-2.0, 2.0)
    assert lidar.range_max == 8.0
    assert lidar.range_min == LDS01_DEFAULTS["range_min"]  # not in the yaml: LDS-01
    assert lidar.rate_hz == LDS01_DEFAULTS["rate_hz"]
    assert lidar.noise_stddev == LDS01_DEFAULTS["noise_stddev"]
    assert lidar.pose == pytest.approx([0.1, 0.0, math.pi], abs=1e-6)
    assert lidar.z == pytest.approx(0.05 + 0.15)
    assert robot.limits == RobotLimits(0.5, -0.1, 2.0, 1.0, 2.0)
    assert _corners(robot.footprint) == _box(-0.18, 0.22, -0.15, 0.15)
    assert robot.height == pytest.approx(0.17)
    assert robot.wheel_separation == pytest.approx(0.34)
    assert robot.wheel_radius == pytest.approx(0.05)


def test_no_sensor_block_and_no_params_lidar_uses_lds01_with_exactly_one_warning(tmp_path,
                                                                                 caplog):
    text = (DATA / "robot_no_sensor.urdf").read_text()
    text = text.replace("package://no_such_description/meshes/", "")  # meshes beside it
    (tmp_path / "robot.urdf").write_text(text.replace('name="laser"', 'name="front_lidar"')
                                         .replace('link="laser"', 'link="front_lidar"'))
    for mesh in ("base.stl", "wheel.dae", "lidar.stl"):
        (tmp_path / mesh).write_text("solid x\nendsolid x\n")
    (tmp_path / "robot.yaml").write_text(
        "max_vel_x: 0.3\nmin_vel_x: 0.0\nmax_vel_theta: 1.0\nacc_lim_x: 1.0\nacc_lim_theta: 1.0\n"
    )
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        robot = load_robot(tmp_path / "robot.urdf")
    warnings = _warnings(caplog)
    assert len(warnings) == 1, warnings
    assert "LDS-01" in warnings[0] and "'front_lidar'" in warnings[0]
    lidar = robot.lidar
    assert lidar.frame == "front_lidar"
    assert (lidar.samples, lidar.angle_min, lidar.angle_max) == (360, 0.0, 2 * math.pi)
    assert (lidar.range_min, lidar.range_max, lidar.rate_hz, lidar.noise_stddev) == (
        0.12, 3.5, 5.0, 0.01)


def test_sensor_block_without_update_rate_takes_the_rate_with_one_warning(tmp_path, caplog):
    text = (DATA / "robot_args.urdf.xacro").read_text().replace(
        "<update_rate>20</update_rate>", "")
    path = tmp_path / "norate.urdf.xacro"
    path.write_text(text)
    shutil.copy(DATA / "robot_no_sensor.yaml", tmp_path / "norate.yaml")
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        robot = load_robot(path)
    assert len(_warnings(caplog)) == 1
    assert "rate_hz" in _warnings(caplog)[0]
    assert robot.lidar.rate_hz == LDS01_DEFAULTS["rate_hz"]
    assert robot.lidar.samples == 180  # the rest still from the sensor block


def test_base_without_base_link_name_is_the_largest_child_of_the_root(tmp_path):
    text = (DATA / "robot_no_sensor.urdf").read_text().replace("base_link", "chassis")
    (tmp_path / "r.urdf").write_text(text)
    shutil.copy(DATA / "robot_no_sensor.yaml", tmp_path / "r.yaml")
    robot = load_robot(tmp_path / "r.urdf")
    assert _corners(robot.footprint) == _box(-0.18, 0.22, -0.15, 0.15)


# ------------------------------------------------------------------------------------------
# Bad input: one InputError naming the file


def _write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _edit_fixture(tmp_path: Path, old: str, new: str, name: str = "bad.urdf") -> Path:
    text = (DATA / "robot_no_sensor.urdf").read_text()
    assert old in text
    path = _write(tmp_path, name, text.replace(old, new))
    shutil.copy(DATA / "robot_no_sensor.yaml", path.with_name(name.split(".")[0] + ".yaml"))
    return path


def _assert_input_error(target, *words, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        load_robot(target, **kwargs)
    message = str(info.value)
    assert "\n" not in message
    for word in words:
        assert word in message, message
    return message


def test_unknown_robot_name_lists_the_robots_with_did_you_mean():
    message = _assert_input_error("turtlebot3_wafle", "robots/turtlebot3_wafle.urdf.xacro",
                                  "did you mean 'turtlebot3_waffle'?", "linorobot2_2wd")
    assert "turtlebot3_burger" in message


@pytest.mark.parametrize("target,words", [
    ("missing/robot.urdf", ("missing/robot.urdf", "no such file")),
    ("worlds/slim_blockage.world", ("slim_blockage.world", "not a robot description")),
    (str(DATA / "robot_broken.urdf"), ("tests/data/robot_broken.urdf", "not XML")),
    (str(DATA / "robot_broken.urdf.xacro"), ("tests/data/robot_broken.urdf.xacro", "not XML")),
    (str(DATA / "robot_not_urdf.urdf"), ("tests/data/robot_not_urdf.urdf", "not a URDF",
                                         "<sdf>")),
])
def test_bad_files(target, words):
    _assert_input_error(target, *words)


def test_xacro_error_names_the_file(tmp_path):
    path = _write(tmp_path, "x.urdf.xacro",
                  '<robot name="x" xmlns:xacro="http://ros.org/wiki/xacro">'
                  '<link name="${no_such_property}"/></robot>')
    _assert_input_error(path, str(path), "xacro", "no_such_property")


def test_no_base_collision(tmp_path):
    path = _edit_fixture(tmp_path, '<box size="0.40 0.30 0.12"/>',
                         '<mesh filename="package://no_such_description/meshes/base.stl"/>')
    _assert_input_error(path, str(path), "no base collision", "'base_link'")


def test_no_wheel_joints(tmp_path):
    text = (DATA / "robot_no_sensor.urdf").read_text().replace('type="continuous"',
                                                                 'type="fixed"')
    path = _write(tmp_path, "nowheels.urdf", text)
    _assert_input_error(path, str(path), "no wheel joints")


def test_one_wheel_is_not_a_differential_drive(tmp_path):
    path = _edit_fixture(tmp_path, '<origin xyz="0 -0.17 0.0"', '<origin xyz="0 0.25 0.0"')
    _assert_input_error(path, str(path), "no wheel joints")


def test_no_lidar_link(tmp_path):
    text = (DATA / "robot_no_sensor.urdf").read_text().replace('"laser"', '"camera"')
    path = _write(tmp_path, "nolidar.urdf", text)
    _assert_input_error(path, str(path), "no lidar", "base_scan", "*_laser")


def test_malformed_sensor_block(tmp_path):
    text = (DATA / "robot_args.urdf.xacro").read_text().replace(
        "<max>6.0</max>", "<max>far</max>")
    path = _write(tmp_path, "badsensor.urdf.xacro", text)
    _assert_input_error(path, str(path), "<range/max>", "'far'")


def test_sensor_block_with_inverted_range(tmp_path):
    text = (DATA / "robot_args.urdf.xacro").read_text().replace("<min>0.05</min>",
                                                                "<min>7.0</min>")
    path = _write(tmp_path, "inverted.urdf.xacro", text)
    _assert_input_error(path, str(path), "range_min < range_max")


def test_joint_to_unknown_link(tmp_path):
    path = _edit_fixture(tmp_path, '<child link="caster"/>', '<child link="castor"/>')
    _assert_input_error(path, str(path), "unknown link 'castor'")


# ------------------------------------------------------------------------------------------
# Limits files


LIMITS_OK = "max_vel_x: 0.3\nmin_vel_x: 0.0\nmax_vel_theta: 1.0\nacc_lim_x: 1.0\n" \
            "acc_lim_theta: 1.5\n"


def test_load_limits(repo_root):
    assert load_limits(repo_root / "params/robots/turtlebot3_burger.yaml") == RobotLimits(
        0.22, -0.22, 2.84, 2.5, 3.2)


@pytest.mark.parametrize("text,words", [
    ("max_vel_x: [0.3\n", ("malformed YAML",)),
    ("- 1\n- 2\n", ("expected a mapping",)),
    (LIMITS_OK + "max_vel_y: 0.0\n", ("unknown key 'max_vel_y'", "did you mean 'max_vel_x'?")),
    (LIMITS_OK + "lidar:\n  sample: 10\n", ("unknown key 'lidar.sample'",
                                            "did you mean 'samples'?")),
    (LIMITS_OK.replace("acc_lim_theta: 1.5\n", ""), ("missing key", "acc_lim_theta")),
    (LIMITS_OK.replace("max_vel_x: 0.3", "max_vel_x: fast"), ("max_vel_x must be a number",)),
    (LIMITS_OK.replace("max_vel_x: 0.3", "max_vel_x: -0.3"), ("max_vel_x must be > 0",)),
    (LIMITS_OK + "lidar:\n  range_min: 5.0\n", ("range_min < range_max",)),
    (LIMITS_OK + "lidar:\n  samples: 10.5\n", ("whole number",)),
    (LIMITS_OK + "robot_radius: 0\n", ("robot_radius must be > 0",)),
    (LIMITS_OK + "robot_raduis: 0.2\n", ("did you mean 'robot_radius'?",)),
])
def test_bad_limits_files(tmp_path, text, words):
    path = _write(tmp_path, "limits.yaml", text)
    with pytest.raises(InputError) as info:
        load_limits(path)
    message = str(info.value)
    assert message.startswith(str(path)), message
    for word in words:
        assert word in message, message


@pytest.mark.parametrize("name, radius", [("turtlebot3_waffle", 0.22),
                                          ("turtlebot3_burger", 0.1),
                                          ("linorobot2_2wd", 0.22)])
def test_costmap_radius_is_the_makers_nav2_value(name, radius):
    assert load_robot(name).costmap_radius == radius


def test_costmap_radius_without_one_in_the_limits_file_is_the_circumscribed(tmp_path):
    shutil.copy(DATA / "robot_no_sensor.urdf", tmp_path / "r.urdf")
    _write(tmp_path, "r.yaml", LIMITS_OK)
    robot = load_robot(tmp_path / "r.urdf")
    assert robot.costmap_radius == robot.radius == pytest.approx(math.hypot(0.22, 0.15))
    _write(tmp_path, "r.yaml", LIMITS_OK + "robot_radius: 0.3\n")
    clear_robot_cache()  # the same modification time, to the file system's resolution
    assert load_robot(tmp_path / "r.urdf").costmap_radius == 0.3


def test_bad_limits_beside_a_robot_fail_its_load(tmp_path):
    shutil.copy(DATA / "robot_no_sensor.urdf", tmp_path / "r.urdf")
    _write(tmp_path, "r.yaml", LIMITS_OK + "acc_lim_z: 1\n")
    _assert_input_error(tmp_path / "r.urdf", str(tmp_path / "r.yaml"), "unknown key 'acc_lim_z'")


def test_resolve_robot_by_name_and_by_path(repo_root):
    assert resolve_robot("linorobot2_2wd") == repo_root / "robots" / "linorobot2_2wd.urdf.xacro"
    assert resolve_robot(DATA / "robot_no_sensor.urdf") == DATA / "robot_no_sensor.urdf"


# ------------------------------------------------------------------------------------------
# The disk cache: a process that finds the model there needs no yourdfpy

_SUBPROCESS_LOAD = """
import json, sys
from swarm_scene.robot_model import load_robot
m = load_robot(sys.argv[1])
print(json.dumps({"yourdfpy": "yourdfpy" in sys.modules, "footprint": m.footprint.tolist(),
                  "lidar": [m.lidar.frame, m.lidar.samples, m.lidar.range_max,
                            m.lidar.pose.tolist()],
                  "max_vel_x": m.limits.max_vel_x, "writeable": m.footprint.flags.writeable
                  or m.lidar.pose.flags.writeable}))
"""


def _load_in_subprocess(robot, cache_dir: Path) -> dict:
    import json
    import os
    import subprocess
    import sys

    env = {**os.environ, "SWARM_WB_CACHE_DIR": str(cache_dir)}
    out = subprocess.run([sys.executable, "-c", _SUBPROCESS_LOAD, str(robot)], env=env,
                         capture_output=True, text=True, check=True, timeout=120)
    return json.loads(out.stdout.strip().splitlines()[-1])


def _robot_in(folder: Path, repo_root: Path) -> Path:
    """A copy of the burger (its sensor block: made without a warning) with its own limits."""
    shutil.copy(repo_root / "robots" / "turtlebot3_burger.urdf.xacro", folder / "r.urdf.xacro")
    _write(folder, "r.yaml", LIMITS_OK)
    return folder / "r.urdf.xacro"


def test_a_second_process_loads_the_model_from_the_disk_cache(tmp_path):
    cache = tmp_path / "cache"
    robot = _load_in_subprocess("turtlebot3_waffle", cache)
    entries = list((cache / "robots").glob("*.pickle"))
    assert robot["yourdfpy"] and len(entries) == 1  # made, then kept
    again = _load_in_subprocess("turtlebot3_waffle", cache)
    assert not again["yourdfpy"]  # found on disk: no URDF parse
    assert {k: v for k, v in again.items() if k != "yourdfpy"} == \
        {k: v for k, v in robot.items() if k != "yourdfpy"}
    assert again["writeable"] is False


def test_the_disk_cache_is_keyed_by_content_and_survives_a_bad_entry(tmp_path, monkeypatch,
                                                                      caplog, repo_root):
    monkeypatch.setenv("SWARM_WB_CACHE_DIR", str(tmp_path / "cache"))
    folder = tmp_path / "robot"
    folder.mkdir()
    source = _robot_in(folder, repo_root)
    with caplog.at_level(logging.WARNING, logger=LOGGER):
        first = load_robot(source)
    assert _warnings(caplog) == [] and first.limits.max_vel_x == pytest.approx(0.3)
    entries = sorted((tmp_path / "cache" / "robots").glob("*.pickle"))
    assert len(entries) == 1
    # another limits file: another entry, and the new limits
    _write(folder, "r.yaml", LIMITS_OK.replace("max_vel_x: 0.3", "max_vel_x: 0.2"))
    clear_robot_cache()
    assert load_robot(source).limits.max_vel_x == pytest.approx(0.2)
    assert len(list((tmp_path / "cache" / "robots").glob("*.pickle"))) == 2
    # a corrupt entry is a miss, made and written again
    _write(folder, "r.yaml", LIMITS_OK)
    entries[0].write_bytes(b"not a pickle")
    clear_robot_cache()
    again = load_robot(source)
    assert again.limits == first.limits
    assert (again.lidar.frame, again.lidar.samples) == (first.lidar.frame, first.lidar.samples)
    np.testing.assert_array_equal(again.lidar.pose, first.lidar.pose)
    np.testing.assert_array_equal(again.footprint, first.footprint)
    assert entries[0].read_bytes() != b"not a pickle"


def test_a_model_made_with_a_warning_is_not_kept_so_the_warning_is_said_again(tmp_path,
                                                                             monkeypatch,
                                                                             caplog):
    monkeypatch.setenv("SWARM_WB_CACHE_DIR", str(tmp_path / "cache"))
    shutil.copy(DATA / "robot_no_sensor.urdf", tmp_path / "r.urdf")
    _write(tmp_path, "r.yaml", LIMITS_OK)  # no lidar block: the LDS-01 defaults, warned
    for _ in range(2):
        clear_robot_cache()
        caplog.clear()
        with caplog.at_level(logging.WARNING, logger=LOGGER):
            load_robot(tmp_path / "r.urdf")
        assert len(_warnings(caplog, "LDS-01")) == 1
    assert not list((tmp_path / "cache").rglob("*.pickle"))


def test_an_empty_cache_dir_setting_turns_the_disk_cache_off(tmp_path, monkeypatch):
    monkeypatch.setenv("SWARM_WB_CACHE_DIR", "")
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    load_robot("turtlebot3_burger")
    assert not (tmp_path / "xdg").exists()
