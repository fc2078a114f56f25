"""What an open dashboard page costs the simulation (not a test): two runs of one seed, compared
second by second.

Run A is ``swarm-up --commanders --rtf 0`` without dashboard; run B the same with ``--dashboard``,
whose page (headless Chromium, one robot's view selected) is opened for ``--on`` and closed for
``--off`` wall seconds, again and again.  Both runs do the same simulated work in every simulated
second (the same seed; the script checks that their task times are equal), so B's wall time per
simulated second divided by A's (``wall_timeline_s`` of ``sim_summary.json``) cancels the work
and leaves B's slow-down; comparing the seconds with the page open with the closed seconds
around them, within run B, cancels this machine's drift from run to run (up to a fifth here).
A closed window's seconds count from ``--settle`` simulated s after the close (the dashboard
keeps reading the swarm for ``idle_grace_s``, 10 s wall) to 4 s before the next open.

Usage (from the repository root; Debian's ``chromium`` needed)::

    python tools/dash_cost.py [--swarm-size 100] [--duration 1100] [--seed 0] [--on 30]
        [--off 40] [--first 50] [--select Srobot7] [--port 8099] [--run-dir DIR]
    python tools/dash_cost.py --analyze DIR    # the figures of runs made before

It prints one line per open window and a summary: the mean slow-down of the windows, its standard
error, and all seconds pooled, as JSON.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from tests.support.browser import Chromium  # noqa: E402

BEFORE_OPEN_S = 4  # [s] simulated: closed seconds this near the next open are left out


def toggle(url: str, select: str, on_s: float, off_s: float, first_s: float, out: Path,
           running) -> None:
    """Open and close the page until the run ends; write ``[[sim_open, sim_close, fps], ...]``
    (the simulated times the page showed 5 s after it opened and when it closed)."""
    windows = []
    time.sleep(first_s)
    with Chromium("about:blank") as browser:
        while running():
            browser.call("Page.navigate", {"url": url})
            try:
                browser.wait_for("window.dash && window.dash.stats().drawn > 0", 30)
                browser.evaluate(f"window.dash.select({json.dumps(select)})")
                time.sleep(5.0)
                s0 = browser.evaluate("window.dash.stats().kpi.sim_time_s")
                time.sleep(max(0.0, on_s - 5.0))
                stats = browser.evaluate("window.dash.stats()")
            except (RuntimeError, AssertionError):  # an error, or wait_for's timeout
                break  # the run ended while the page was open
            windows.append([s0, stats["kpi"]["sim_time_s"], stats["fps"]])
            print(f"dash_cost: page open from {s0:.0f} to {windows[-1][1]:.0f} s simulated, "
                  f"{stats['fps']:.2f} updates/s", flush=True)
            out.write_text(json.dumps(windows))
            browser.call("Page.navigate", {"url": "about:blank"})
            time.sleep(off_s)


def analyze(run_dir: Path, settle_s: int) -> dict:
    """The slow-down [%] of the open windows of ``run_dir/B`` against their closed neighbours,
    each second's wall time divided by ``run_dir/A``'s."""
    a, b = (json.loads((run_dir / x / "metrics.json").read_text()) for x in "AB")
    if a["task_times_s"] != b["task_times_s"]:
        raise SystemExit("dash_cost: the two runs differ in their task times: not the same work")
    ta, tb = (json.loads((run_dir / x / "sim_summary.json").read_text())["wall_timeline_s"]
              for x in "AB")
    n = min(len(ta), len(tb))
    da = [ta[0]] + [ta[k] - ta[k - 1] for k in range(1, n)]
    db = [tb[0]] + [tb[k] - tb[k - 1] for k in range(1, n)]
    windows = json.loads((run_dir / "windows.json").read_text())
    opened = [range(int(s0) + 1, min(int(s1), n)) for s0, s1, _ in windows]
    ends = [settle_s + 6] + [int(s1) + settle_s for _, s1, _ in windows]
    starts = [int(s0) - BEFORE_OPEN_S for s0, _, _ in windows] + [n]
    closed = [range(max(e, 0), min(s, n)) for e, s in zip(ends, starts, strict=True)]

    def ratio(seconds) -> float:
        return sum(db[k] for k in seconds) / sum(da[k] for k in seconds)

    rows = []
    for i, on in enumerate(opened):
        around = [*closed[i], *closed[i + 1]]
        if len(on) and around:
            rows.append(100.0 * (1.0 - ratio(around) / ratio(on)))
            print(f"dash_cost: open {on.start}-{on.stop} s: slow-down {rows[-1]:+.1f} % against "
                  f"the {len(around)} closed s around it")
    all_on = [k for r in opened for k in r]
    all_off = [k for r in closed for k in r]
    return {"windows": len(rows), "slowdown_mean_pct": round(statistics.mean(rows), 2),
            "slowdown_se_pct": round(statistics.stdev(rows) / math.sqrt(len(rows)), 2)
            if len(rows) > 1 else None,
            "slowdown_min_pct": round(min(rows), 2), "slowdown_max_pct": round(max(rows), 2),
            "slowdown_pooled_pct": round(100.0 * (1.0 - ratio(all_off) / ratio(all_on)), 2),
            "seconds_open": len(all_on), "seconds_closed": len(all_off),
            "updates_per_s_min": min(w[2] for w in windows), "rtf_a": a["rtf"], "rtf_b": b["rtf"],
            "tasks": len(a["task_times_s"])}


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--swarm-size", type=int, default=100)
    p.add_argument("--duration", type=float, default=1100.0, help="simulated s per run")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--on", type=float, default=30.0, help="wall s the page stays open")
    p.add_argument("--off", type=float, default=40.0, help="wall s the page stays closed")
    p.add_argument("--first", type=float, default=50.0,
                   help="wall s after the navigators are ready before the first open")
    p.add_argument("--settle", type=int, default=14,
                   help="simulated s after a close before the closed seconds count")
    p.add_argument("--select", default="Srobot7", help="the robot whose view the page shows")
    p.add_argument("--port", type=int, default=8099)
    p.add_argument("--run-dir", type=Path, default=None,
                   help="where runs A and B go (default: runs/dash-cost-<timestamp>)")
    p.add_argument("--analyze", type=Path, default=None, metavar="DIR",
                   help="only analyse the runs in DIR")
    a = p.parse_args()
    if a.analyze is not None:
        print(json.dumps(analyze(a.analyze, a.settle)))
        return 0
    run_dir = a.run_dir or ROOT / "runs" / time.strftime("dash-cost-%Y%m%d-%H%M%S")
    run_dir.mkdir(parents=True, exist_ok=True)
    swarm_up = str(Path(sys.executable).with_name("swarm-up"))
    base = [swarm_up, "--swarm-size", str(a.swarm_size), "--commanders", "--rtf", "0",
            "--duration", str(a.duration), "--seed", str(a.seed)]
    for name in "AB":
        extra = ["--dashboard", str(a.port)] if name == "B" else []
        log = run_dir / f"{name}.log"
        with open(log, "w") as out:
            proc = subprocess.Popen([*base, *extra, "--run-dir", str(run_dir / name)],
                                    stdout=out, stderr=subprocess.STDOUT, env=os.environ)
        print(f"dash_cost: run {name} ({'with' if extra else 'without'} dashboard), log {log}",
              flush=True)
        if extra:
            deadline = time.monotonic() + 120.0
            while "navigators ready in" not in log.read_text() and time.monotonic() < deadline:
                time.sleep(1.0)
            toggle(f"http://127.0.0.1:{a.port}/", a.select, a.on, a.off, a.first,
                   run_dir / "windows.json", lambda p=proc: p.poll() is None)
        if proc.wait() != 0:
            raise SystemExit(f"dash_cost: run {name} failed, see {log}")
    print(json.dumps(analyze(run_dir, a.settle)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
