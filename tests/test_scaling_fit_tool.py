"""``tools/scaling_fit.py``: the scaling model's fit recovers the constants runs were made with."""

from __future__ import annotations

import json

import pytest

from swarm_common.paths import ROOT
from tests.support.tools import load_tool

SCRIPT = ROOT / "tools" / "scaling_fit.py"


@pytest.fixture(scope="module")
def tool():
    return load_tool("scaling_fit")


def _run(n: int, s: float, g: float, o: float, a: float, b: float) -> dict:
    t = s * n + (g + o) * n / 2 + b * n / 2 + a  # one host, 2 cores, 2 group processes
    return {"robots": n, "rtf": 1.0 / t,
            "cpu_ms_per_robot_per_sim_s": {"sim": s * 1e3, "group": g * 1e3, "swarm-up": o * 1e3}}


def test_the_fit_recovers_a_and_b_and_predicts_the_runs(tool, tmp_path):
    a, b = 0.012, 0.0015
    runs = [_run(n, 0.0004, 0.004 + 2e-5 * n, 0.0003, a, b) for n in (20, 50, 100, 200)]
    got_a, got_b = tool.fit(runs, cores=2)
    assert got_a == pytest.approx(a, rel=1e-9)
    assert got_b == pytest.approx(b, rel=1e-9)
    t, terms = tool.predict(100, [100], 2, 2, 0.0004, 0.006, 0.0003, got_a, got_b)
    assert 1.0 / t == pytest.approx(runs[2]["rtf"], rel=1e-9)
    assert set(terms) == {"simulator", "hosts", "spread", "hand-overs", "link"}


def test_the_link_prices_the_remote_robots_only(tool):
    _, one = tool.predict(1000, [1000], 8, 8, 0.0, 0.0, 0.0, 0.0, 0.0, w=1000.0)
    _, ten = tool.predict(1000, [100] * 10, 8, 80, 0.0, 0.0, 0.0, 0.0, 0.0, w=1000.0, link=1e6)
    assert one["link"] == 0.0
    assert ten["link"] == pytest.approx(900 * 1000.0 / 1e6)


def test_the_command_line_writes_the_fit(tool, tmp_path):
    import subprocess
    import sys

    paths = []
    for n in (20, 50, 100, 200):
        p = tmp_path / f"one_{n}.json"
        p.write_text(json.dumps(_run(n, 0.0004, 0.005, 0.0003, 0.01, 0.001)))
        paths.append(str(p))
    out = subprocess.run([sys.executable, str(SCRIPT), "--fit", *paths, "--json",
                          str(tmp_path / "fit.json")], capture_output=True, text=True)
    assert out.returncode == 0, out.stderr
    fit = json.loads((tmp_path / "fit.json").read_text())
    assert fit["a_s"] == pytest.approx(0.01) and fit["b_s"] == pytest.approx(0.001)
    assert all(abs(r["error"]) < 1e-9 for r in fit["runs"])
