"""``swarm-up``'s validation in process: default map and the navigator template's strict check."""

import shutil

import pytest
import yaml

from swarm_common import paths
from swarm_common.errors import InputError
from swarm_up.args import build_parser, validate
from swarm_up.rundir import CONTEXT_KEYS, check_nav_template, load_nav_template


def _validate(tmp_path, *args):
    return validate(build_parser().parse_args([*args, "--run-dir", str(tmp_path / "run")]))


def test_bundled_world_takes_its_bundled_map(tmp_path):
    cfg = _validate(tmp_path, "--world", "slim_blockage", "--swarm-size", "2")
    assert cfg.map_path == paths.MAPS_DIR / "slim_blockage.yaml"


def test_world_by_path_is_rasterised_not_given_the_bundled_map_of_its_name(tmp_path):
    """A user's edited copy of slim_blockage must not be driven on the original's map."""
    for suffix in (".world", ".yaml"):
        name = f"slim_blockage{suffix}"
        shutil.copy(paths.WORLDS_DIR / name, tmp_path / name)
    cfg = _validate(tmp_path, "--world", str(tmp_path / "slim_blockage.world"),
                    "--swarm-size", "2")
    assert cfg.world_path == tmp_path / "slim_blockage.world"
    assert cfg.map_path is None  # prepare_map rasterises RUN/map.yaml from the world itself
    assert not (tmp_path / "run").exists()


def _template(tmp_path, params: dict):
    path = tmp_path / "navigator.yaml"
    path.write_text(yaml.safe_dump({"navigator": {"ros__parameters": params}}))
    return path


def test_the_bundled_template_passes(tmp_path):
    path = paths.PARAMS_DIR / "navigator.yaml"
    check_nav_template(path, load_nav_template(path))


def test_context_keys_pass_and_misspelt_keys_do_not(tmp_path):
    params = {"use_sim_time": True, "robot": "turtlebot3_burger", "inflation_radius": 0.6}
    path = _template(tmp_path, params)
    check_nav_template(path, load_nav_template(path))
    path = _template(tmp_path, {**params, "inflation_raduis": 0.6})
    with pytest.raises(InputError) as err:
        check_nav_template(path, load_nav_template(path))
    assert str(err.value) == (f"{path}: inflation_raduis: unknown navigator parameter "
                              "(did you mean 'inflation_radius'?)")


def test_nav_params_misspelt_key_names_flag_file_and_key(tmp_path):
    path = _template(tmp_path, {"max_vel_x": 0.26, "max_vle_theta": 1.0})
    with pytest.raises(InputError) as err:
        _validate(tmp_path, "--nav-params", str(path))
    assert str(err.value) == (f"--nav-params: {path}: max_vle_theta: unknown navigator "
                              "parameter (did you mean 'max_vel_theta'?)")
    path = _template(tmp_path, {"max_vel_x": -0.1})
    with pytest.raises(InputError, match=r"^--nav-params: .*navigator.yaml: max_vel_x: must be"):
        _validate(tmp_path, "--nav-params", str(path))


def test_context_keys_are_the_nodes():
    from swarm_nav.node import _CONTEXT_PARAMS

    assert CONTEXT_KEYS == {*_CONTEXT_PARAMS, "use_sim_time"}


def test_per_robot_processes_are_refused_beyond_what_one_host_serves():
    """Issue 38 item 5: a process per navigator and per commander at 60 robots is more than 120
    DDS participants, the most one host serves in one domain (swarm_up.args
    MAX_PARTICIPANTS_PER_HOST): refused before anything starts, with what to use instead."""
    from swarm_up.args import MAX_PARTICIPANTS_PER_HOST, participants

    def run(*flags):
        return validate(build_parser().parse_args(list(flags)))

    with pytest.raises(InputError) as err:
        run("--swarm-size", "60", "--commanders", "--processes", "per-robot")
    assert str(err.value).startswith("--processes: per-robot runs 60 robots as 123 DDS "
                                     "participants")
    assert "use --processes K" in str(err.value)
    assert participants(58, True, False, False) <= MAX_PARTICIPANTS_PER_HOST
    assert run("--swarm-size", "58", "--commanders", "--processes", "per-robot").groups is None
    # in group processes, 60 robots are a handful of participants
    assert run("--swarm-size", "60", "--commanders").groups is not None
    assert participants(60, True, False, False, groups=2) == 5
    # another rank of a run over two hosts runs no simulator and no metrics listener, but a
    # link to the other hosts; rank 0 with the Discovery Server runs one more
    assert participants(10, True, False, False, leader=False, hosts=2) == 22
    assert participants(10, True, True, True, leader=True, hosts=2,
                        discovery_server=True) == 27


def test_commanders_on_a_world_without_workstations_are_refused_up_front(tmp_path):
    with pytest.raises(InputError) as err:
        _validate(tmp_path, "--world", "empty", "--commanders", "--swarm-size", "2")
    assert str(err.value) == ("--commanders: world empty has no workstations to visit (none in "
                              "empty.yaml); run it without --commanders, or add workstations")
    shutil.copy(paths.WORLDS_DIR / "empty.world", tmp_path / "bare.world")  # no .yaml beside it
    with pytest.raises(InputError, match=r"^--commanders: world bare has no workstations to "
                                         r"visit \(no bare.yaml beside it\)"):
        _validate(tmp_path, "--world", str(tmp_path / "bare.world"), "--commanders")
    assert not (tmp_path / "run").exists()  # nothing started
    _validate(tmp_path, "--world", "empty", "--swarm-size", "2")  # without commanders: runs
