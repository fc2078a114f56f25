"""swarm-map: writes a map_server map of a world; bad input exits 2 with one line."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swarm_scene.map_io import load_map
from swarm_scene.rasterize import rasterize_world
from swarm_scene.world import load_world
from swarm_sim import map_cli

DATA = Path(__file__).resolve().parents[1] / "data"


def _run(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "swarm_sim.map_cli", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=60)


def test_writes_the_world_map_at_the_default_prefix(tmp_path):
    res = _run("slim_blockage", cwd=tmp_path)
    assert res.returncode == 0, res.stderr
    assert res.stderr == ""
    yaml_path, pgm_path = tmp_path / "slim_blockage.yaml", tmp_path / "slim_blockage.pgm"
    assert yaml_path.is_file() and pgm_path.is_file()
    assert "381 x 311 cells at 0.05 m/cell" in res.stdout
    assert "slim_blockage.yaml" in res.stdout and "slim_blockage.pgm" in res.stdout
    occ = load_map(yaml_path)
    expected = rasterize_world(load_world("slim_blockage"), resolution=0.05)
    np.testing.assert_array_equal(occ.data, expected.data)
    assert occ.origin == pytest.approx([-9.0, -5.5, 0.0])


def test_resolution_and_output_prefix(tmp_path, capsys):
    (tmp_path / "out").mkdir()
    code = map_cli.main(["empty", "--resolution", "0.1", "--output", str(tmp_path / "out/room")])
    assert code == 0
    out = capsys.readouterr().out
    # walls span [-10.15, 10.15]; padded to [-10.65, 10.65]; origin snapped down to -10.7:
    # ceil((10.65 + 10.7) / 0.1) = 214 cells
    assert "214 x 214 cells at 0.1 m/cell, origin (-10.7, -10.7) m" in out
    occ = load_map(tmp_path / "out" / "room.yaml")
    assert occ.resolution == pytest.approx(0.1)
    assert occ.data.shape == (214, 214)


def test_world_given_by_path_reports_skipped_elements(tmp_path, capsys):
    code = map_cli.main([str(DATA / "world_unsupported.world"), "-o", str(tmp_path / "u")])
    assert code == 0
    captured = capsys.readouterr()
    assert captured.err.count("\n") == 1
    assert "warning: world_unsupported.world: skipped unsupported elements: " in captured.err
    assert "actor 'walker'" in captured.err
    occ = load_map(tmp_path / "u.yaml")
    assert (occ.data == 100).sum() == 80 * 4  # the one 4 x 0.2 m wall, 0.05 m cells


def test_help_exits_0_and_documents_the_options(tmp_path):
    res = _run("--help", cwd=tmp_path)
    assert res.returncode == 0
    for option in ("WORLD", "--resolution", "--output", "PREFIX", "[m/cell]"):
        assert option in res.stdout


BAD_INPUTS = [
    (["slim_blokage"], "unknown world 'slim_blokage' (did you mean 'slim_blockage'?)"),
    (["missing.world"], "missing.world: no such world file"),
    (["bad.world"], "bad.world: malformed XML"),
    ([], "the following arguments are required: WORLD"),
    (["empty", "--resolution", "-0.05"], "--resolution: must be a positive number"),
    (["empty", "--resolution", "abc"], "--resolution: must be a positive number, got 'abc'"),
    (["empty", "--output", "no/such/dir/m"], "--output: directory 'no/such/dir' does not exist"),
    (["empty", "--z-min", "3", "--z-max", "1"], "--z-max: must be above --z-min"),
    (["empty", "--colour", "red"], "unrecognized arguments: --colour red"),
]


def _check_one_error_line(code: int, out: str, err: str, message: str, tmp_path: Path) -> None:
    assert code == 2
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("swarm-map: error: ")
    assert message in lines[0]
    assert "Traceback" not in err
    assert list(tmp_path.iterdir()) == [tmp_path / "bad.world"]  # nothing written


@pytest.mark.parametrize(("args", "message"), BAD_INPUTS[:4])
def test_bad_input_exits_2_with_one_line_as_a_process(tmp_path, args, message):
    (tmp_path / "bad.world").write_text("<sdf><world name='w'><model></world></sdf>")
    res = _run(*args, cwd=tmp_path)
    _check_one_error_line(res.returncode, res.stdout, res.stderr, message, tmp_path)


@pytest.mark.parametrize(("args", "message"), BAD_INPUTS)
def test_bad_input_exits_2_with_one_line(tmp_path, monkeypatch, capsys, args, message):
    (tmp_path / "bad.world").write_text("<sdf><world name='w'><model></world></sdf>")
    monkeypatch.chdir(tmp_path)
    code = map_cli.main(args)
    captured = capsys.readouterr()
    _check_one_error_line(code, captured.out, captured.err, message, tmp_path)


def test_console_script_is_installed(tmp_path):
    script = Path(sys.executable).parent / "swarm-map"
    if not script.exists():
        pytest.skip("swarm-map console script not installed in this environment")
    res = subprocess.run([str(script), "nope"], cwd=tmp_path, capture_output=True, text=True,
                         timeout=60)
    assert res.returncode == 2
    assert res.stderr.count("\n") == 1 and "unknown world 'nope'" in res.stderr
