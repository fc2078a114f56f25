"""``swarm-bench``: flags, the summary's arithmetic, the plot, and real sweeps.

The contract: docs/reference/contract.md#s2, #s6.

The sweeps start the installed console script (``.venv/bin/swarm-bench``) as a user does, with
2-3 robots and a few simulated seconds; every process they start is stopped in a ``finally``.
"""

from __future__ import annotations

import contextlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from swarm_bench.bench import build_parser, summarize, swarm_up_command, validate, write_plot
from swarm_up.args import default_processes
from tests.support.ros import alive

SWARM_BENCH = Path(sys.executable).parent / "swarm-bench"
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
RECORD_KEYS = {"kind", "size", "run", "seed", "command", "exit_code", "interrupted", "log",
               "cpu_s", "cpu_source", "cpu_per_robot", "rss_mb_per_robot", "metrics"}
METRICS_KEYS = {"robots", "sim_time_s", "wall_time_s", "rtf", "robot_ticks_per_s",
                "tasks_completed", "throughput_per_hour", "goals_reached", "goals_aborted",
                "collisions", "min_separation_m", "late_ticks", "cpu_percent",
                "peak_rss_mb_per_robot", "processes"}
TOP_KEYS = {"command", "git", "machine", "settings", "records", "summary", "interrupted",
            "exit_code"}


# ------------------------------------------------------------------------------------ pure parts
def _swarm(n: int, r: int, rtf: float, **metrics) -> dict:
    m = {"robots": n, "rtf": rtf, "robot_ticks_per_s": rtf * 10 * n, "throughput_per_hour": 20.0,
         "goals_reached": 4, "goals_aborted": 0, "min_separation_m": 0.3 + r,
         "collisions": {"robot_robot": r, "robot_wall": 0}, "processes": "per-robot", **metrics}
    return {"kind": "swarm", "size": n, "run": r, "exit_code": 0, "metrics": m,
            "cpu_per_robot": 0.01 * (r + 1), "rss_mb_per_robot": 100.0}


def test_summary_means_extremes_and_share_of_baseline():
    records = [_swarm(5, 0, 2.0), _swarm(5, 1, 4.0),
               {"kind": "baseline", "size": 5, "exit_code": 0,
                "baseline": {"rtf": 12.0, "robot_ticks_per_s": 600.0, "cpu_per_robot": 0.002}},
               _swarm(20, 0, 1.0) | {"exit_code": 1}]
    s5, s20 = summarize((5, 20, 50), records)
    assert (s5["size"], s5["runs"], s5["runs_ok"]) == (5, 2, 2)
    assert (s5["rtf_mean"], s5["rtf_min"], s5["rtf_max"]) == (3.0, 2.0, 4.0)
    assert s5["robot_ticks_per_s_mean"] == pytest.approx(150.0)
    assert s5["collisions_robot_robot_mean"] == 0.5
    assert s5["min_separation_m"] == pytest.approx(0.3)
    assert s5["cpu_per_robot_mean"] == pytest.approx(0.015)
    assert s5["baseline_rtf"] == 12.0
    assert s5["rtf_pct_of_baseline"] == pytest.approx(25.0)
    # A failed run is counted but not averaged; a size without records is left out.
    assert (s20["runs"], s20["runs_ok"], s20["rtf_mean"], s20["baseline_rtf"]) == (
        1, 0, None, None)


def test_plot_is_a_png_with_or_without_rows(tmp_path):
    records = [_swarm(2, 0, 3.0), _swarm(3, 0, 2.5),
               {"kind": "baseline", "size": 3, "exit_code": 0, "baseline": {"rtf": 9.0}}]
    for name, summary in (("full.png", summarize((2, 3), records)), ("empty.png", [])):
        write_plot(tmp_path / name, summary, "test")
        assert (tmp_path / name).read_bytes()[:8] == PNG_MAGIC


def test_ready_timeout_is_passed_to_swarm_up_only_when_given(tmp_path):
    base = ["--run-dir", str(tmp_path), "--swarm-up", sys.executable]
    cfg = validate(build_parser().parse_args(base))
    assert "--ready-timeout" not in swarm_up_command(cfg, 5, 0, tmp_path, tmp_path / "m.json")
    cfg = validate(build_parser().parse_args([*base, "--ready-timeout", "900"]))
    argv = swarm_up_command(cfg, 1000, 0, tmp_path, tmp_path / "m.json")
    assert argv[-2:] == ["--ready-timeout", "900"]


def test_defaults_are_the_issues():
    args = build_parser().parse_args([])
    assert args.sizes == (5, 20, 50, 100)
    assert (args.duration, args.runs, args.world, args.seed) == (300.0, 1, "slim_blockage", 0)
    assert (args.coordination, args.processes, args.baseline) == ("decentralized", None, False)


# ------------------------------------------------------------------------------------ bad flags
BAD_FLAGS = [
    (["--sizes", "0,5"], "--sizes"),
    (["--sizes", "5,x"], "--sizes"),
    (["--sizes", ""], "--sizes"),
    (["--sizes", "5,5"], "--sizes"),
    (["--sizes", "2.5"], "--sizes"),
    (["--duration", "-3"], "--duration"),
    (["--duration", "0"], "--duration"),
    (["--duration", "inf"], "--duration"),
    (["--runs", "0"], "--runs"),
    (["--runs", "two"], "--runs"),
    (["--seed", "-1"], "--seed"),
    (["--world", "no_such_world"], "--world"),
    (["--coordination", "anarchy"], "--coordination"),
    (["--processes", "0"], "--processes"),
    (["--processes", "some"], "--processes"),
    (["--plot", "/no/such/dir/bench.png"], "--plot"),
    (["--plot", "bench.jpg"], "--plot"),
    (["--output", "/no/such/dir/bench.json"], "--output"),
    (["--swarm-up", "/no/such/swarm-up"], "--swarm-up"),
    (["--swarm-up", "/etc/passwd"], "--swarm-up"),  # not executable
    (["--ready-timeout", "0"], "--ready-timeout"),
    (["--ready-timeout", "soon"], "--ready-timeout"),
    (["--frobnicate"], "--frobnicate"),
]


@pytest.mark.e2e
@pytest.mark.parametrize(("args", "flag"), BAD_FLAGS, ids=[" ".join(a) for a, _ in BAD_FLAGS])
def test_bad_flag_exits_2_with_one_line(args, flag, tmp_path):
    res = subprocess.run([str(SWARM_BENCH), *args, "--run-dir", str(tmp_path / "runs")],
                         capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert res.returncode == 2, res.stdout + res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1, res.stderr
    assert lines[0].startswith("swarm-bench: error: ") and flag in lines[0], lines[0]
    assert "Traceback" not in res.stderr
    assert not (tmp_path / "runs").exists()  # nothing started


# -------------------------------------------------------------------------------------- sweeps
class Bench:
    """One ``swarm-bench`` run in a session of its own; leaving stops everything it started."""

    def __init__(self, args: list[str], tmp_path: Path):
        self.out = tmp_path / "bench.json"
        self.png = tmp_path / "bench.png"
        self.argv = [str(SWARM_BENCH), *args, "--output", str(self.out), "--plot",
                     str(self.png), "--run-dir", str(tmp_path / "runs")]
        self.stdout = tmp_path / "bench.stdout"
        self.stderr = tmp_path / "bench.stderr"
        self.known: dict[int, psutil.Process] = {}
        with open(self.stdout, "wb") as out, open(self.stderr, "wb") as err:
            self.proc = subprocess.Popen(self.argv, stdout=out, stderr=err, cwd=tmp_path,
                                         stdin=subprocess.DEVNULL, start_new_session=True)

    def track(self) -> None:
        """Remember every descendant (they run in sessions of their own)."""
        with contextlib.suppress(psutil.Error):
            for p in psutil.Process(self.proc.pid).children(recursive=True):
                self.known.setdefault(p.pid, p)

    def wait(self, timeout: float, until=None) -> int | None:
        """Wait for the exit (or for ``until()`` to hold); fail after ``timeout`` wall s."""
        deadline = time.monotonic() + timeout
        while self.proc.poll() is None:
            if until is not None and until():
                return None
            assert time.monotonic() < deadline, f"swarm-bench still running\n{self.output()}"
            self.track()
            time.sleep(0.3)
        return self.proc.returncode

    def output(self) -> str:
        return (f"command: {' '.join(self.argv)}\n--- stdout:\n"
                f"{self.stdout.read_text(errors='replace')[-3000:]}\n--- stderr:\n"
                f"{self.stderr.read_text(errors='replace')[-3000:]}")

    def result(self) -> dict:
        return json.loads(self.out.read_text())

    def alive(self) -> list[psutil.Process]:
        return alive(self.known.values())

    def __enter__(self) -> Bench:
        return self

    def __exit__(self, *exc) -> None:
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(10.0)
        for p in self.alive():
            with contextlib.suppress(psutil.Error):
                p.kill()
        psutil.wait_procs(list(self.known.values()), timeout=5.0)


@pytest.mark.e2e
def test_small_sweep_with_baseline_writes_table_json_and_plot(tmp_path):
    duration = 5
    with Bench(["--sizes", "2,3", "--duration", str(duration), "--baseline"], tmp_path) as bench:
        code = bench.wait(600.0)
        assert code == 0, bench.output()
        assert not bench.alive(), [p.pid for p in bench.alive()]
        doc = bench.result()
    assert TOP_KEYS <= doc.keys()
    assert doc["command"][0] == "swarm-bench" and doc["exit_code"] == 0
    assert doc["machine"]["cores"] == os.cpu_count() and doc["machine"]["rclpy"]
    assert doc["interrupted"] is False
    swarm = [r for r in doc["records"] if r["kind"] == "swarm"]
    assert [r["size"] for r in swarm] == [2, 3]
    for rec in swarm:
        assert RECORD_KEYS <= rec.keys()
        assert METRICS_KEYS <= rec["metrics"].keys()
        m = rec["metrics"]
        assert rec["exit_code"] == 0
        assert m["robots"] == rec["size"]
        assert m["sim_time_s"] == pytest.approx(duration)
        assert m["rtf"] > 0 and m["robot_ticks_per_s"] > 0
        assert rec["cpu_per_robot"] > 0 and rec["rss_mb_per_robot"] > 0
        assert rec["cpu_source"] in ("bench", "swarm-up")
        assert "--commanders" in rec["command"] and rec["command"][:1] == [
            str(Path(sys.executable).parent / "swarm-up")]
        assert rec["command"][rec["command"].index("--rtf") + 1] == "0"
    baselines = [r for r in doc["records"] if r["kind"] == "baseline"]
    assert [r["size"] for r in baselines] == [2, 3]
    for rec in baselines:
        f = rec["baseline"]
        assert rec["exit_code"] == 0
        assert f["ticks"] == duration * 10 and f["late_ticks"] == 0 and f["rtf"] > 0
        assert f["processes"] == default_processes(rec["size"])  # what swarm-up chose
    assert [s["size"] for s in doc["summary"]] == [2, 3]
    for s in doc["summary"]:
        assert s["rtf_mean"] > 0 and s["baseline_rtf"] > 0
        assert s["rtf_pct_of_baseline"] == pytest.approx(100 * s["rtf_mean"] / s["baseline_rtf"])
    assert bench.png.read_bytes()[:8] == PNG_MAGIC
    table = bench.stdout.read_text()
    assert "% of" in table and "ticks/s" in table and "CPU/robot" in table


@pytest.mark.e2e
def test_interrupted_bench_keeps_the_finished_rows(tmp_path):
    with Bench(["--sizes", "2,3", "--duration", "5"], tmp_path) as bench:

        def first_record() -> bool:
            with contextlib.suppress(OSError, ValueError):
                return len(bench.result()["records"]) >= 1
            return False

        assert bench.wait(300.0, until=first_record) is None, bench.output()
        bench.track()
        t0 = time.monotonic()
        os.kill(bench.proc.pid, signal.SIGINT)
        code = bench.wait(60.0)
        took = time.monotonic() - t0
        assert code == 130, bench.output()
        assert not bench.alive(), [p.cmdline() for p in bench.alive()]
        doc = bench.result()
    assert took < 40.0
    assert doc["interrupted"] is True and doc["exit_code"] == 130
    assert [(r["kind"], r["size"], r["exit_code"]) for r in doc["records"]] == [("swarm", 2, 0)]
    assert [s["size"] for s in doc["summary"]] == [2]
    assert bench.png.read_bytes()[:8] == PNG_MAGIC
    assert "interrupted" in bench.stderr.read_text()


@pytest.mark.e2e
def test_a_swarm_up_that_cannot_run_exits_2_with_one_line(tmp_path):
    fake = tmp_path / "swarm-up"
    fake.write_text("not a program\n")
    fake.chmod(0o755)  # executable, but no format the kernel runs
    res = subprocess.run([str(SWARM_BENCH), "--swarm-up", str(fake), "--sizes", "2",
                          "--duration", "1", "--output", str(tmp_path / "b.json"),
                          "--plot", str(tmp_path / "b.png"), "--run-dir", str(tmp_path / "runs")],
                         capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert res.returncode == 2, res.stdout + res.stderr
    assert res.stderr.strip().splitlines() == [
        f"swarm-bench: error: --swarm-up: cannot run '{fake}': Exec format error"]
