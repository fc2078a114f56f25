"""End to end: ``swarm-up --dashboard`` watched by headless Chromium, as a user would.

A 4-robot run with commanders, paced at 3 times real time; the browser opens the printed URL
while the swarm comes up and stays until the run has ended.  The page must have drawn every
robot, received >= 5 updates a second, and its last KPIs (sent after the simulator's last tick,
while swarm-up stops its children) must equal the figures of the run's ``metrics.json``.
"""

from __future__ import annotations

import socket
import statistics
import time

import pytest

from tests.support.browser import Chromium, require_chromium
from tests.test_e2e_swarm_up import EXIT_SLACK_S, READY_TIMEOUT_S, SwarmUp

pytestmark = pytest.mark.e2e

N = 4
DURATION_S = 60.0
RTF = 3.0  # 20 wall seconds


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_dashboard_shows_the_run_and_its_metrics(tmp_path):
    require_chromium()
    # Paced: the page needs 60 frames (10 s at 6 a second) for its rate, and 4 robots unpaced now
    # finish the simulated minute in about 6 s.
    args = ["--swarm-size", str(N), "--commanders", "--rtf", str(RTF), "--duration",
            str(DURATION_S), "--dashboard", str(_free_port())]
    with SwarmUp(args, tmp_path, "dash") as run:
        url = run.wait_for_stdout(r"dashboard: (http://127\.0\.0\.1:\d+/)", 60.0).group(1)
        with Chromium(url) as browser:
            samples = []
            deadline = time.monotonic() + READY_TIMEOUT_S + DURATION_S + EXIT_SLACK_S
            while run.proc.poll() is None:
                assert time.monotonic() < deadline, run.diagnostics()
                run.track()
                try:
                    stats = browser.evaluate("window.dash && window.dash.stats()")
                except RuntimeError:
                    stats = None
                if stats:
                    samples.append(stats)
                time.sleep(0.3)
            assert run.proc.returncode == 0, run.diagnostics()
            last = browser.evaluate("window.dash.stats()")
        metrics = run.metrics()
    assert samples, "the page never ran its script"
    assert max(s["drawn"] for s in samples) == N, samples[-1]
    assert last["robots"] == N
    rates = [s["fps"] for s in samples if s["frames"] >= 60]
    assert rates and statistics.median(rates) >= 5.0, rates
    kpi = last["kpi"]
    assert kpi["sim_time_s"] == pytest.approx(metrics["sim_time_s"], abs=0.15), kpi
    assert kpi["tasks"] == metrics["tasks_completed"] > 0, kpi
    assert kpi["goals_aborted"] == metrics["goals_aborted"]
    assert kpi["collisions"] == sum(metrics["collisions"].values())
    assert kpi["late_ticks"] == metrics["late_ticks"]
