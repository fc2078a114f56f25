"""Every bad input exits 2 with one stderr line naming the flag, and no traceback.

The contract: docs/reference/contract.md#s2.
"""

import socket
import subprocess
import sys

import pytest

BAD = [
    (["--swarm-size", "0"], "--swarm-size"),
    (["--swarm-size", "-3"], "--swarm-size"),
    (["--swarm-size", "abc"], "--swarm-size"),
    (["--swarm-size", "2.5"], "--swarm-size"),
    (["--swarm-size"], "--swarm-size"),
    (["--rtf", "-1"], "--rtf"),
    (["--rtf", "fast"], "--rtf"),
    (["--rtf", "nan"], "--rtf"),
    (["--rtf", "inf"], "--rtf"),
    (["--duration", "-5"], "--duration"),
    (["--duration", "0"], "--duration"),
    (["--duration", "1min"], "--duration"),
    (["--seed", "-1"], "--seed"),
    (["--seed", "x"], "--seed"),
    (["--processes", "0"], "--processes"),
    (["--processes", "-2"], "--processes"),
    (["--processes", "many"], "--processes"),
    (["--ready-timeout", "0"], "--ready-timeout"),
    (["--name-prefix", "3robot"], "--name-prefix"),
    (["--name-prefix", "my-robot"], "--name-prefix"),
    (["--coordination", "anarchic"], "--coordination"),
    (["--coordination", "centralized"], "--coordination"),
    (["--assignment", "route"], "--assignment"),
    (["--waiting-spots", "near", "--commanders"], "--waiting-spots"),
    (["--coordination", "centralized", "--commanders", "--assignment", "best"],
     "--assignment"),
    (["--coordination", "centralized", "--commanders", "--silence-timeout", "-1"],
     "--silence-timeout"),
    (["--policy", "pipelined", "--commanders"], "--policy"),
    (["--coordination", "centralized", "--commanders", "--policy", "eager"], "--policy"),
    (["--coordination", "centralized", "--commanders", "--eta-speed", "0.3"], "--eta-speed"),
    (["--coordination", "centralized", "--commanders", "--policy", "pipelined",
      "--dock-clear", "-1"], "--dock-clear"),
    (["--service-time", "15"], "--service-time"),
    (["--commanders", "--service-time", "-1"], "--service-time"),
    (["--record", "run.txt"], "--record"),
    (["--record", "/nonexistent_dir_xyz/run.mcap"], "--record"),
    (["--record", "/tmp"], "--record"),
    (["--record-topics", "odom"], "--record-topics"),
    (["--record", "run.mcap", "--record-topics", "(odom"], "--record-topics"),
    (["--record", "run.mcap", "--record-topics", "^/nothing$"], "--record-topics"),
    (["--dashboard", "99999"], "--dashboard"),
    (["--dashboard", "0"], "--dashboard"),
    (["--dashboard", "http"], "--dashboard"),
    (["--dashboard", "80.5"], "--dashboard"),
    (["--foxglove", "70000"], "--foxglove"),
    (["--foxglove", "8080", "--dashboard", "8080"], "--foxglove"),
    (["--headless", "--gui"], "--gui"),
    (["--metrics", "/nonexistent_dir_xyz/m.json"], "--metrics"),
    (["--map", "/nonexistent_dir_xyz/map.yaml"], "--map"),
    (["--world", "no_such_world"], "--world"),
    (["--world", "/nonexistent_dir_xyz/w.world"], "--world"),
    (["--robot", "no_such_robot"], "--robot"),
    (["--robot", "/nonexistent_dir_xyz/r.urdf"], "--robot"),
    (["--nav-params", "/nonexistent_dir_xyz/navigator.yaml"], "--nav-params"),
    (["--bogus"], "--bogus"),
]


def _run(args, cwd):
    return subprocess.run([sys.executable, "-m", "swarm_up.cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=60)


@pytest.mark.parametrize(("args", "flag"), BAD, ids=lambda v: " ".join(v) if isinstance(v, list)
                         else None)
def test_bad_input_exits_2_with_one_line(args, flag, tmp_path):
    res = _run([*args, "--run-dir", str(tmp_path / "run")], tmp_path)
    lines = [ln for ln in res.stderr.splitlines() if ln.strip()]
    assert res.returncode == 2, res.stderr
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("swarm-up: error: "), lines[0]
    assert flag in lines[0]
    assert "Traceback" not in res.stderr + res.stdout
    assert not (tmp_path / "run").exists()  # nothing started, nothing written


@pytest.mark.parametrize("flag", ["--dashboard", "--foxglove"])
def test_a_live_view_port_in_use_exits_2_with_one_line(tmp_path, flag):
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        res = _run([flag, str(port), "--run-dir", str(tmp_path / "run")], tmp_path)
    assert res.returncode == 2
    assert res.stderr.splitlines() == [
        f"swarm-up: error: {flag}: port {port} on 127.0.0.1 is in use"]
    assert not (tmp_path / "run").exists()


def test_help_names_the_dashboard_and_markers():
    res = _run(["--help"], None)
    assert res.returncode == 0
    assert "--markers" in res.stdout and "127.0.0.1" in res.stdout and "8080" in res.stdout


def test_run_dir_that_is_a_file(tmp_path):
    target = tmp_path / "afile"
    target.write_text("x")
    res = _run(["--run-dir", str(target)], tmp_path)
    assert res.returncode == 2
    assert res.stderr.strip().splitlines() == [
        f"swarm-up: error: --run-dir: '{target}' exists and is not a directory"]


def test_metrics_path_that_is_a_directory(tmp_path):
    res = _run(["--metrics", str(tmp_path), "--run-dir", str(tmp_path / "r")], tmp_path)
    assert res.returncode == 2
    assert len(res.stderr.strip().splitlines()) == 1 and "--metrics" in res.stderr


def test_misspelt_nav_params_key_exits_2_naming_file_and_key(tmp_path):
    template = tmp_path / "navigator.yaml"
    template.write_text("navigator:\n  ros__parameters:\n    inflation_raduis: 0.6\n")
    res = _run(["--nav-params", str(template), "--run-dir", str(tmp_path / "run")], tmp_path)
    assert res.returncode == 2
    assert res.stderr.splitlines() == [
        f"swarm-up: error: --nav-params: {template}: inflation_raduis: unknown navigator "
        "parameter (did you mean 'inflation_radius'?)"]
    assert not (tmp_path / "run").exists()


def test_help_lists_every_option():
    res = _run(["--help"], None)
    assert res.returncode == 0
    for flag in ("--swarm-size", "--world", "--map", "--robot", "--name-prefix", "--seed",
                 "--rtf", "--duration", "--commanders", "--coordination", "--metrics",
                 "--record", "--record-topics", "--dashboard", "--markers", "--faults",
                 "--processes", "--headless", "--gui", "--run-dir", "--ready-timeout"):
        assert flag in res.stdout
    assert "not implemented" not in res.stdout  # every flag it lists works
