"""The one command-line helper: a parser raising InputError, typed validators, one name rule."""

import argparse
import math

import pytest

from swarm_common import cli
from swarm_common.errors import InputError, run_cli


def _parser() -> cli.ArgumentParser:
    p = cli.ArgumentParser(prog="demo")
    p.add_argument("--count", type=cli.positive_int, default=1)
    p.add_argument("--prefix", type=cli.ros_name, default="Srobot")
    return p


def test_parser_errors_are_one_input_error_naming_the_flag():
    with pytest.raises(InputError) as err:
        _parser().parse_args(["--count", "0"])
    assert str(err.value) == "--count: must be a positive integer, got '0'"
    with pytest.raises(InputError, match="^unrecognized arguments: --bogus$"):
        _parser().parse_args(["--bogus"])
    with pytest.raises(InputError, match="^--count: expected one argument$"):
        _parser().parse_args(["--count"])


def test_run_cli_turns_a_bad_flag_into_one_line_and_exit_2(capsys):
    code = run_cli("demo", lambda: _parser().parse_args(["--prefix", "_x"]) and 0)
    assert code == 2
    err = capsys.readouterr().err
    assert err.splitlines() == [
        "demo: error: --prefix: must be a ROS name (letters, digits and '_', starting with a "
        "letter, no '__'), got '_x'"]


def test_help_still_exits_0(capsys):
    with pytest.raises(SystemExit) as done:
        _parser().parse_args(["--help"])
    assert done.value.code == 0
    assert "--count" in capsys.readouterr().out


@pytest.mark.parametrize(("check", "good", "bad"), [
    (cli.positive_int, [("1", 1), ("120", 120)], ["0", "-3", "2.5", "abc", ""]),
    (cli.non_negative_int, [("0", 0), ("7", 7)], ["-1", "1.0", "x"]),
    (cli.seed, [("0", 0), ("4294967296", 4294967296)], ["-1", "x"]),
    (cli.port, [("1", 1), ("8765", 8765), ("65535", 65535)], ["0", "65536", "-1", "http"]),
    (cli.finite_float, [("-2.5", -2.5), ("0", 0.0), ("1e3", 1000.0)], ["nan", "inf", "-inf", "m"]),
    (cli.non_negative_float, [("0", 0.0), ("0.5", 0.5)], ["-0.1", "nan", "inf", "fast"]),
    (cli.positive_float, [("0.05", 0.05), ("300", 300.0)], ["0", "-1", "nan", "inf", "1min"]),
])
def test_validators(check, good, bad):
    for text, value in good:
        got = check(text)
        assert got == value and type(got) is type(value), text
    for text in bad:
        with pytest.raises(argparse.ArgumentTypeError, match=f"got {text!r}$"):
            check(text)


@pytest.mark.parametrize("name", ["Srobot", "S", "robot_1", "R2D2", "a_b_c"])
def test_ros_names_accepted(name):
    assert cli.is_ros_name(name)
    assert cli.ros_name(name) == name


# The rule of design.ros2.org/articles/topic_and_service_names.html, plus no leading '_'.
@pytest.mark.parametrize("name", [
    "", "3robot", "_x", "__ns", "my-robot", "a__b", "robot/1", " Srobot", "Srobot ",
    "Sröbot", "робот", "Srobot\n", "a.b",
])
def test_ros_names_rejected(name):
    assert not cli.is_ros_name(name)
    with pytest.raises(argparse.ArgumentTypeError, match="must be a ROS name"):
        cli.ros_name(name)


@pytest.mark.parametrize(("text", "ok"), [
    ("Srobot3", True), ("/Srobot3", True), ("fleet/Srobot3", True), ("/fleet/a_1", True),
    ("fleet//Srobot3", False), ("fleet/", False), ("/", False), ("3x", False),
    ("fleet/_x", False), ("flé/x", False),
])
def test_ros_namespace(text, ok):
    assert cli.is_ros_namespace(text) is ok


def test_ros_names_comma_list():
    assert cli.ros_names("Srobot1,Srobot2") == ("Srobot1", "Srobot2")
    assert cli.ros_names(" /Srobot1 , Srobot2/ ,") == ("Srobot1", "Srobot2")
    for text in ("", ",", "Srobot1,_x", "Srobot1,3a", "a,b-c"):
        with pytest.raises(argparse.ArgumentTypeError, match="comma-separated list of ROS names"):
            cli.ros_names(text)


def test_float_validators_refuse_every_non_finite_value():
    for check in (cli.finite_float, cli.non_negative_float, cli.positive_float):
        for text in ("nan", "NaN", "inf", "-Infinity"):
            with pytest.raises(argparse.ArgumentTypeError):
                check(text)
    assert math.isfinite(cli.positive_float("1e-300"))
