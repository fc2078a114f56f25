"""``swarm-up --robot`` as a mixed fleet: the run's models, interleaved; bad mixes exit 2 with one
line naming ``--robot``; every robot's navigator params fitted to its own model."""

from __future__ import annotations

import subprocess
import sys
from collections import Counter

import pytest
import yaml

from swarm_common import paths
from swarm_common.errors import InputError
from swarm_scene.robot_model import load_robot
from swarm_up.args import build_parser, validate
from swarm_up.children import child_specs
from swarm_up.rundir import load_nav_template, robot_params, write_params_files

MIX = "turtlebot3_waffle:12,turtlebot3_burger:4,linorobot2_2wd:4"
TEMPLATE = load_nav_template(paths.PARAMS_DIR / "navigator.yaml")


def _validate(tmp_path, *args):
    return validate(build_parser().parse_args([*args, "--run-dir", str(tmp_path / "run")]))


# -- the run's models --------------------------------------------------------------------------


def test_a_mix_gives_every_robot_its_model_interleaved(tmp_path):
    cfg = _validate(tmp_path, "--swarm-size", "20", "--robot", MIX)
    assert len(cfg.robots) == 20 and len(cfg.models) == 20
    assert Counter(cfg.models) == {"turtlebot3_waffle": 12, "turtlebot3_burger": 4,
                                   "linorobot2_2wd": 4}
    assert cfg.models[:5] == ("turtlebot3_waffle", "turtlebot3_burger", "turtlebot3_waffle",
                              "linorobot2_2wd", "turtlebot3_waffle")
    assert cfg.robot == MIX  # what the simulator and the coordinator get
    sim = next(s for s in child_specs(cfg) if s.name == "sim")
    assert sim.argv[sim.argv.index("--robot") + 1] == MIX


def test_without_swarm_size_a_mix_sets_it(tmp_path):
    cfg = _validate(tmp_path, "--robot", "turtlebot3_burger:2,linorobot2_2wd:1")
    assert cfg.robots == ("Srobot1", "Srobot2", "Srobot3")
    assert cfg.models == ("turtlebot3_burger", "linorobot2_2wd", "turtlebot3_burger")
    assert len(_validate(tmp_path).robots) == 5  # one model: the default size


def test_one_model_stays_as_it_was(tmp_path):
    cfg = _validate(tmp_path, "--swarm-size", "3", "--robot", "turtlebot3_burger")
    assert cfg.robot == "turtlebot3_burger" and cfg.fleet == ()
    assert cfg.models == ("turtlebot3_burger",) * 3


def test_a_fleet_file_names_paths_relative_to_itself(tmp_path, repo_root):
    (tmp_path / "r").mkdir()
    urdf = tmp_path / "r" / "bot.urdf.xacro"
    urdf.write_text((repo_root / "robots" / "turtlebot3_burger.urdf.xacro").read_text())
    fleet = tmp_path / "fleet.yaml"
    fleet.write_text("fleet:\n  - {robot: turtlebot3_waffle, count: 2}\n"
                     "  - {robot: r/bot.urdf.xacro, count: 1}\n")
    cfg = _validate(tmp_path, "--robot", str(fleet))
    assert cfg.models == ("turtlebot3_waffle", str(urdf.resolve()), "turtlebot3_waffle")
    assert cfg.robot == f"turtlebot3_waffle:2,{urdf.resolve()}:1"


@pytest.mark.parametrize("args, message", [
    (["--swarm-size", "19", "--robot", MIX],
     f"--robot: the counts of '{MIX}' add up to 20, not to --swarm-size 19"),
    (["--robot", "turtlebot3_waffle:3,turtlebot3_burger:0"],
     "--robot: 'turtlebot3_burger:0': the count must be a positive integer, got '0'"),
    (["--robot", "turtlebot3_waffle:x,turtlebot3_burger:1"],
     "--robot: 'turtlebot3_waffle:x': the count must be a positive integer, got 'x'"),
    (["--robot", "turtlebot3_waffle:2,turtlebot3_burger"],
     "--robot: 'turtlebot3_burger': a mix needs NAME:COUNT for every model"),
    (["--robot", "turtlebot3_wafle:2,turtlebot3_burger:1"],
     "--robot: robots/turtlebot3_wafle.urdf.xacro: unknown robot 'turtlebot3_wafle' (did you "
     "mean 'turtlebot3_waffle'?); available: linorobot2_2wd, turtlebot3_burger, "
     "turtlebot3_waffle"),
])
def test_bad_mix_names_robot(tmp_path, args, message):
    with pytest.raises(InputError) as err:
        _validate(tmp_path, *args)
    assert str(err.value) == message


def test_bad_mix_exits_2_with_one_line(tmp_path):
    res = subprocess.run([sys.executable, "-m", "swarm_up.cli", "--swarm-size", "4", "--robot",
                          "turtlebot3_waffle:2,turtlebot3_burger:1", "--run-dir",
                          str(tmp_path / "run")], capture_output=True, text=True, timeout=60,
                         cwd=tmp_path)
    assert res.returncode == 2
    assert res.stderr.splitlines() == [
        "swarm-up: error: --robot: the counts of 'turtlebot3_waffle:2,turtlebot3_burger:1' "
        "add up to 3, not to --swarm-size 4"]
    assert not (tmp_path / "run").exists()


def test_spawn_fit_uses_the_largest_robot(tmp_path, monkeypatch):
    import swarm_up.args as args_mod

    radii = []
    real = args_mod.spawn_poses
    monkeypatch.setattr(args_mod, "spawn_poses",
                        lambda area, n, radius, *a, **k: radii.append(radius) or real(
                            area, n, radius, *a, **k))
    _validate(tmp_path, "--robot", "turtlebot3_burger:3,turtlebot3_waffle:1")
    assert radii == [load_robot("turtlebot3_waffle").radius]


# -- navigator params, one model per robot -----------------------------------------------------


@pytest.mark.parametrize("name", ["turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd"])
def test_fitted_params_respect_the_models_limits(name):
    model = load_robot(name)
    got = robot_params(TEMPLATE, model)
    lim = model.limits
    assert got["robot_radius"] == model.costmap_radius
    # the template's margin kept: 0.55 - 0.22 today
    margin = TEMPLATE["inflation_radius"] - TEMPLATE["robot_radius"]
    assert got["inflation_radius"] >= got["robot_radius"] + margin - 1e-9
    assert got["inflation_radius"] >= TEMPLATE["inflation_radius"]
    for key, limit in (("max_vel_x", lim.max_vel_x), ("max_vel_theta", lim.max_vel_theta),
                       ("acc_lim_x", lim.acc_lim_x), ("acc_lim_theta", lim.acc_lim_theta),
                       ("rotate_to_heading_angular_vel", lim.max_vel_theta)):
        assert got[key] == min(TEMPLATE[key], limit), key  # never above; tighter kept
    assert got["min_vel_x"] == max(TEMPLATE["min_vel_x"], lim.min_vel_x)
    assert got["decel_lim_x"] == max(TEMPLATE["decel_lim_x"], -lim.acc_lim_x)
    assert got["backup_speed"] <= -lim.min_vel_x


def test_the_waffle_keeps_the_template_unchanged():
    """The template is written for the waffle: fitting changes none of its values."""
    got = robot_params(TEMPLATE, load_robot("turtlebot3_waffle"))
    assert got == {key: TEMPLATE[key] for key in got}


def test_a_bigger_robot_gets_a_wider_inflation():
    big = type("Model", (), {"costmap_radius": 0.4, "limits": load_robot(
        "turtlebot3_waffle").limits})()
    got = robot_params(TEMPLATE, big)
    assert got["robot_radius"] == 0.4
    assert got["inflation_radius"] == pytest.approx(0.4 + 0.33)


def test_each_params_file_names_its_own_robot(tmp_path):
    cfg = _validate(tmp_path, "--swarm-size", "6", "--robot",
                    "turtlebot3_waffle:2,turtlebot3_burger:2,linorobot2_2wd:2")
    files = write_params_files(cfg, load_nav_template(cfg.nav_template))
    for path, ns, name in zip(files, cfg.robots, cfg.models, strict=True):
        params = yaml.safe_load(path.read_text())[f"/{ns}/navigator"]["ros__parameters"]
        assert params["robot"] == name
        assert params["robot_radius"] == load_robot(name).costmap_radius
        assert params["max_vel_x"] <= load_robot(name).limits.max_vel_x
    burger = yaml.safe_load(files[1].read_text())["/Srobot2/navigator"]["ros__parameters"]
    assert (burger["robot"], burger["robot_radius"], burger["max_vel_x"]) == (
        "turtlebot3_burger", 0.1, 0.22)
