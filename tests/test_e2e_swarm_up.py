"""End-to-end tests of ``swarm-up`` (issue 4), run as a user runs them.

Every test starts the installed console script (``.venv/bin/swarm-up``) as a subprocess with
``--run-dir`` in ``tmp_path``, so each run's logs land in ``RUN/logs/``; a failed assertion shows
the tail of swarm-up's own output and of those logs.  The session's ``ROS_DOMAIN_ID`` (see
``tests/conftest.py``) keeps the runs apart from anything else on the machine.  Every process a
test starts (swarm-up and all it started, which run in sessions of their own) is stopped in a
``finally``.

What is checked (docs/reference/contract.md#s2, #s5, #s6):

1. a 6-robot run with commanders, 180 simulated s: no collision, no aborted goal, every robot
   reaches goals, no late tick;
2. the same command twice gives the same simulated figures (the synchronous control loop);
3. a navigator killed with SIGKILL is restarted within 2 s and its robot goes on;
4. Ctrl-C stops everything within 5 s, exit 0, no process and no stale shared-memory file left;
5. every bad input exits 2 with one line on stderr naming the flag (or the file), no traceback.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from swarm_up import shm
from tests.support.ros import alive

pytestmark = pytest.mark.e2e

SWARM_UP = Path(sys.executable).parent / "swarm-up"

# Figures that depend on the wall clock or the machine's load, not on the simulation: left out of
# the determinism comparison.  Everything else in the metrics must be identical for one seed.
WALL_CLOCK_KEYS = frozenset({
    "wall_time_s",
    "orchestrator_wall_time_s",
    "rtf",
    "robot_ticks_per_s",
    "spawn_to_ready_s",
    "cpu_percent",
    "peak_rss_mb_per_robot",
    "sim_peak_rss_mb",
    "run_dir",
})
PER_ROBOT_WALL_CLOCK_KEYS = frozenset({"ready_s"})

READY_TIMEOUT_S = 150.0  # wall s from start to "all N navigators ready" (a busy 2-core machine)
EXIT_SLACK_S = 120.0  # wall s beyond the simulated duration for a run to end


# ------------------------------------------------------------------------------------ helpers
def _tail(path: Path, n: int) -> str:
    try:
        lines = path.read_text(errors="replace").splitlines()
    except OSError as exc:
        return f"  <{exc.strerror}>"
    return "\n".join(f"  {ln}" for ln in lines[-n:]) or "  <empty>"


def _has_error(path: Path) -> bool:
    """Whether a log has an error line (a program's ``error:``, an ``[ERROR]``, a traceback)."""
    try:
        text = path.read_text(errors="replace")
    except OSError:
        return False
    return re.search(r"error:|\[ERROR\]|^Traceback", text, re.MULTILINE) is not None


class SwarmUp:
    """One ``swarm-up`` run: started in a session of its own, output to files in ``tmp_path``.

    Use as a context manager: leaving it stops swarm-up and every process it started.

    Args:
        args: the command-line arguments (``--run-dir`` is added).
        tmp_path: the test's directory.
        name: the run's name (run directory ``tmp_path/name``).
        wrap: ``wrap(argv)`` -> the command line that runs it (None: as it is).
        env: its environment (None: this process's).
    """

    def __init__(self, args: list[str], tmp_path: Path, name: str = "run",
                 wrap=None, env: dict | None = None):
        self.run_dir = tmp_path / name
        self.logs = self.run_dir / "logs"
        self.out_path = tmp_path / f"{name}.stdout"
        self.err_path = tmp_path / f"{name}.stderr"
        self.argv = [str(SWARM_UP), *args, "--run-dir", str(self.run_dir)]
        if wrap is not None:  # e.g. run it in a network namespace (tests/support/netns.py)
            self.argv = wrap(self.argv)
        self.known: dict[int, psutil.Process] = {}  # every descendant seen, by pid
        with open(self.out_path, "wb") as out, open(self.err_path, "wb") as err:
            self.proc = subprocess.Popen(self.argv, stdin=subprocess.DEVNULL, stdout=out,
                                         stderr=err, cwd=tmp_path, start_new_session=True,
                                         env=env)
        self.t0 = time.monotonic()
        self.track()

    def __enter__(self) -> SwarmUp:
        return self

    def __exit__(self, *exc) -> None:
        self.cleanup()

    # -------------------------------------------------------------- watching
    def track(self) -> list[psutil.Process]:
        """Remember swarm-up's current descendants (they outlive it in their own sessions)."""
        try:
            children = psutil.Process(self.proc.pid).children(recursive=True)
        except psutil.Error:
            return []
        for p in children:
            self.known.setdefault(p.pid, p)
        return children

    def stdout(self) -> str:
        return self.out_path.read_text(errors="replace")

    def stderr(self) -> str:
        return self.err_path.read_text(errors="replace")

    def wait_for_stdout(self, pattern: str, timeout: float) -> re.Match:
        """Poll swarm-up's stdout until ``pattern`` appears; fail if it exits or times out."""
        deadline = time.monotonic() + timeout
        while True:
            m = re.search(pattern, self.stdout(), re.MULTILINE)
            if m:
                self.track()
                return m
            if self.proc.poll() is not None:
                raise AssertionError(f"swarm-up exited with {self.proc.returncode} before "
                                     f"printing {pattern!r}\n{self.diagnostics()}")
            if time.monotonic() > deadline:
                raise AssertionError(f"no {pattern!r} in swarm-up's output after {timeout:g} s"
                                     f"\n{self.diagnostics()}")
            self.track()
            time.sleep(0.2)

    def wait(self, timeout: float) -> int:
        """Wait for swarm-up to exit; fail with the logs after ``timeout`` wall s."""
        deadline = time.monotonic() + timeout
        while self.proc.poll() is None:
            if time.monotonic() > deadline:
                raise AssertionError(f"swarm-up still running after {timeout:g} s"
                                     f"\n{self.diagnostics()}")
            self.track()
            time.sleep(0.2)
        return self.proc.returncode

    def metrics(self, path: Path | None = None) -> dict:
        path = path if path is not None else self.run_dir / "metrics.json"
        try:
            return json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise AssertionError(f"no metrics in {path}: {exc}\n{self.diagnostics()}") from None

    def diagnostics(self, n: int = 12, logs: tuple[str, ...] | None = None) -> str:
        """The tail of ``RUN/logs/*.log`` (or only ``logs``) and of swarm-up's stdout/stderr.

        What says most comes last, where a CI excerpt of the end still shows it: the logs
        with an error line after the others, swarm-up's own output at the end."""
        paths = (sorted(self.logs.glob("*.log")) if logs is None
                 else [self.logs / f"{name}.log" for name in logs])
        paths.sort(key=lambda path: _has_error(path))  # stable: by name within each kind
        parts = [f"command: {' '.join(self.argv)}"]
        for path in paths:
            parts.append(f"--- {path}:\n{_tail(path, n)}")
        parts += [f"--- swarm-up stdout:\n{_tail(self.out_path, n)}",
                  f"--- swarm-up stderr:\n{_tail(self.err_path, n)}"]
        return "\n".join(parts)

    # -------------------------------------------------------------- stopping
    def alive_descendants(self) -> list[psutil.Process]:
        """The remembered descendants still running (zombies count as gone)."""
        return alive(self.known.values())

    def cleanup(self) -> None:
        """Stop swarm-up (SIGINT, then SIGKILL) and kill whatever it started that is left."""
        self.track()
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(self.proc.pid, signal.SIGINT)
            try:
                self.proc.wait(10.0)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(5.0)
        for p in self.alive_descendants():
            with contextlib.suppress(psutil.Error, ProcessLookupError, PermissionError):
                os.killpg(p.pid, signal.SIGKILL)  # children lead their own groups
            with contextlib.suppress(psutil.Error):
                p.kill()
        psutil.wait_procs(list(self.known.values()), timeout=5.0)


def _cmd(p: psutil.Process) -> str:
    try:
        return " ".join(p.cmdline()[:3])
    except psutil.Error as exc:
        return f"<{type(exc).__name__}>"


def _simulated(metrics: dict) -> dict:
    """The metrics without the wall-clock figures (see WALL_CLOCK_KEYS)."""
    out = {k: v for k, v in metrics.items() if k not in WALL_CLOCK_KEYS}
    out["per_robot"] = {
        ns: {k: v for k, v in fig.items() if k not in PER_ROBOT_WALL_CLOCK_KEYS}
        for ns, fig in (metrics.get("per_robot") or {}).items()
    }
    return out


def _diff(a: dict, b: dict, prefix: str = "") -> list[str]:
    """Human-readable differences between two nested dicts."""
    out = []
    for key in sorted(set(a) | set(b)):
        va, vb = a.get(key, "<missing>"), b.get(key, "<missing>")
        if isinstance(va, dict) and isinstance(vb, dict):
            out += _diff(va, vb, f"{prefix}{key}.")
        elif va != vb:
            out.append(f"{prefix}{key}: {va!r} != {vb!r}")
    return out


def _run_to_end(args: list[str], tmp_path: Path, name: str, duration_s: float):
    """Run swarm-up until it exits by itself; returns (exit code, metrics, diagnostics)."""
    with SwarmUp(args, tmp_path, name) as run:
        code = run.wait(READY_TIMEOUT_S + duration_s + EXIT_SLACK_S)
        diag = run.diagnostics()
        assert code == 0, f"swarm-up exited with {code}\n{diag}"
        return code, run.metrics(), diag


# -------------------------------------------------------------------------- 1. a whole run
RUN_180 = ["--swarm-size", "6", "--commanders", "--rtf", "0", "--duration", "180",
           "--metrics", "m.json"]


@pytest.fixture(scope="module")
def run_180(tmp_path_factory):
    """The 6-robot, 180-simulated-s run (test 1 checks it, test 2 repeats it)."""
    tmp = tmp_path_factory.mktemp("run180")
    _, metrics, diag = _run_to_end(RUN_180, tmp, "first", 180)
    from_flag = json.loads((tmp / "m.json").read_text())
    assert from_flag == metrics, "--metrics and RUN/metrics.json differ"
    return metrics, diag


def test_six_robots_with_commanders_run_clean(run_180):
    m, diag = run_180
    msg = f"metrics: {json.dumps(m, indent=1)}\n{diag}"
    assert m["robots"] == 6, msg
    assert m["sim_time_s"] == 180, msg
    assert m["collisions"] == {"robot_robot": 0, "robot_wall": 0}, msg
    assert m["goals_aborted"] == 0, msg
    assert m["goals_reached"] >= 6, msg
    assert sorted(m["per_robot"]) == [f"Srobot{i}" for i in range(1, 7)], msg
    lazy = {ns: fig["goals_reached"] for ns, fig in m["per_robot"].items()
            if fig["goals_reached"] < 1}
    assert not lazy, f"robots that reached no goal: {lazy}\n{msg}"
    assert all(fig["collisions"] == 0 and fig["goals_aborted"] == 0
               for fig in m["per_robot"].values()), msg
    assert m["late_ticks"] == 0, msg
    assert m["restarts"] == 0, msg
    assert m["goal_wait_timeouts"] == 0, msg
    assert m["reproducible"] is True, msg


# ------------------------------------------------------------------------- 2. determinism
def test_same_seed_gives_same_simulated_figures(run_180, tmp_path):
    first, diag1 = run_180
    _, second, diag2 = _run_to_end(RUN_180, tmp_path, "second", 180)
    # No wall-clock timeout decides anything simulated (the commanders are in the lockstep):
    # however busy the machine, the run is reproducible, the first time.
    assert second.get("reproducible") is True, f"the repeated run is not reproducible\n{diag2}"
    a, b = _simulated(first), _simulated(second)
    assert a["goals_reached"] > 0, f"the run did nothing\n{diag1}"
    # Every key is compared, bar the wall-clock ones; a new key must be listed there or agree.
    assert set(first) == set(second), (f"keys in one run only: "
                                       f"{sorted(set(first) ^ set(second))}\n{diag2}")
    diffs = _diff(a, b)
    late = (first.get("late_ticks"), second.get("late_ticks"))
    waits = (first.get("goal_wait_timeouts"), second.get("goal_wait_timeouts"))
    assert not diffs, (f"simulated figures differ between two identical runs (late ticks "
                       f"{late[0]} / {late[1]}, goal-wait timeouts {waits[0]} / {waits[1]}):\n  "
                       + "\n  ".join(diffs)
                       + f"\nfirst run:\n{diag1}\nsecond run:\n{diag2}")


# ------------------------------------------------------------------ 3. a killed navigator
def _navigators_of(run: SwarmUp, ns: str) -> list[psutil.Process]:
    found = []
    for p in run.track():
        with contextlib.suppress(psutil.Error):
            cmd = p.cmdline()
            if f"__ns:=/{ns}" in cmd and any(Path(c).name == "swarm-nav" for c in cmd[:2]):
                found.append(p)
    return found


def test_killed_navigator_is_restarted_and_goes_on(tmp_path):
    args = ["--swarm-size", "4", "--commanders", "--rtf", "3", "--duration", "60",
            "--metrics", "m.json", "--processes", "per-robot"]
    with SwarmUp(args, tmp_path) as run:
        run.wait_for_stdout(r"all 4 navigators ready", READY_TIMEOUT_S)
        nav_log = run.logs / "nav_Srobot2.log"
        assert nav_log.is_file(), run.diagnostics()
        navs = _navigators_of(run, "Srobot2")
        assert len(navs) == 1, f"navigator processes of Srobot2: {navs}\n{run.diagnostics()}"
        old = navs[0]
        log_before = nav_log.read_text(errors="replace")

        old.send_signal(signal.SIGKILL)
        killed_at = time.time()
        new = []
        deadline = time.monotonic() + 15.0
        while not new and time.monotonic() < deadline:
            new = [p for p in _navigators_of(run, "Srobot2") if p.pid != old.pid]
            time.sleep(0.02)
        assert new, f"Srobot2's navigator not restarted within 15 s\n{run.diagnostics()}"
        delay = new[0].create_time() - killed_at
        assert delay <= 2.0, (f"Srobot2's navigator restarted {delay:.2f} s after SIGKILL "
                              f"(the contract: within 2 s)\n{run.diagnostics()}")

        code = run.wait(60 + EXIT_SLACK_S)
        diag = run.diagnostics(n=25, logs=("sim", "nav_Srobot2", "cmd_Srobot2"))
        assert code == 0, f"swarm-up exited with {code}\n{diag}"
        m = run.metrics(tmp_path / "m.json")
        msg = f"metrics: {json.dumps(m, indent=1)}\n{diag}"
        assert m["restarts"] >= 1, msg
        assert m["collisions"] == {"robot_robot": 0, "robot_wall": 0}, msg
        assert "nav_Srobot2" in run.stderr() and "restarted" in run.stderr(), msg
        # The restarted navigator takes a goal again: its commander goes on with the task.
        # (Whether Srobot2 also *reaches* a goal within the 60 s is a matter of timing: the
        # restart costs ~24 simulated s at rtf 3 and its first goal is ~50 s away, so that is
        # not asserted.)
        after = nav_log.read_text(errors="replace")[len(log_before):]
        assert "--- swarm-up: restart" in after, msg
        restarted_part = after.split("--- swarm-up: restart", 1)[1]
        assert re.search(r"\]: goal \d", restarted_part), (
            f"no goal line in Srobot2's navigator log after its restart\n{msg}")
        assert "Traceback" not in restarted_part, msg
        assert m["per_robot"]["Srobot2"]["collisions"] == 0, msg


# ----------------------------------------------------------------------------- 4. Ctrl-C
def test_ctrl_c_leaves_nothing_behind(tmp_path):
    shm_before = shm.snapshot()
    with SwarmUp(["--swarm-size", "3", "--commanders", "--rtf", "1"], tmp_path) as run:
        run.wait_for_stdout(r"all 3 navigators ready", READY_TIMEOUT_S)
        time.sleep(1.0)  # let the commanders send their first goals
        descendants = run.track()
        names = {p.pid: _cmd(p) for p in descendants}
        assert len(descendants) >= 7, f"expected sim + 3 navigators + 3 commanders: {names}"

        os.kill(run.proc.pid, signal.SIGINT)  # the terminal's Ctrl-C reaches swarm-up only
        sent = time.monotonic()
        with contextlib.suppress(subprocess.TimeoutExpired):
            run.proc.wait(30.0)
        took = time.monotonic() - sent
        diag = run.diagnostics()
        assert run.proc.returncode is not None, f"swarm-up ignores SIGINT\n{diag}"
        assert run.proc.returncode == 0, f"exit code {run.proc.returncode}\n{diag}"
        assert took <= 5.0, f"swarm-up took {took:.1f} s to stop after Ctrl-C\n{diag}"

        left = run.alive_descendants()  # every descendant ever seen, not only those above
        assert not left, (f"processes left after Ctrl-C: "
                          f"{[(p.pid, names.get(p.pid) or _cmd(p)) for p in left]}\n{diag}")
        stale = shm.stale_files(shm_before, min_age_s=0.0)
        ages = {p.name: round(time.time() - p.lstat().st_ctime, 2) for p in stale if p.exists()}
        assert not stale, f"stale shared-memory files left (age [s]): {ages}\n{diag}"
        assert "Traceback" not in run.stdout() + run.stderr(), diag


# -------------------------------------------------------------------------- 5. bad input
BROKEN_WORLD = """<?xml version="1.0"?>
<sdf version="1.6">
  <world name="broken">
    <model name="wall">
      <link name="link">
        <collision name="c"><geometry><box><size>1 1 1</size></box></geometry>
      </link>
  </world>
"""

# (arguments, the flag the line must name, wall-time limit [s]); "{broken}" is the broken world.
BAD_INPUT = [
    (["--swarm-size", "0"], "--swarm-size", 15),
    (["--swarm-size", "-3"], "--swarm-size", 15),
    (["--swarm-size", "abc"], "--swarm-size", 15),
    (["--rtf", "-1"], "--rtf", 15),
    (["--duration", "-5"], "--duration", 15),
    (["--world", "nope"], "--world", 15),
    (["--world", "/nonexistent.world"], "--world", 15),
    (["--robot", "nope"], "--robot", 15),
    (["--map", "/nonexistent.yaml"], "--map", 15),
    (["--processes", "0"], "--processes", 15),
    (["--processes", "xyz"], "--processes", 15),
    # Found out late (the spawn grid by the simulator, the world when it is loaded): still "a
    # few seconds", generous for a busy machine.
    (["--swarm-size", "500"], "--swarm-size", 15),
    (["--world", "{broken}"], "--world", 15),
]


@pytest.mark.parametrize(("args", "flag", "limit_s"), BAD_INPUT,
                         ids=[" ".join(a).replace("{broken}", "broken.world")
                              for a, _, _ in BAD_INPUT])
def test_bad_input_exits_2_with_one_line(args, flag, limit_s, tmp_path):
    broken = tmp_path / "broken.world"
    broken.write_text(BROKEN_WORLD)
    args = [str(broken) if a == "{broken}" else a for a in args]
    run_dir = tmp_path / "run"
    argv = [str(SWARM_UP), *args, "--run-dir", str(run_dir)]
    t0 = time.monotonic()
    with subprocess.Popen(argv, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                          stderr=subprocess.PIPE, text=True, cwd=tmp_path,
                          start_new_session=True) as proc:
        try:
            out, err = proc.communicate(timeout=limit_s + 60)
        finally:
            if proc.poll() is None:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(proc.pid, signal.SIGKILL)
                proc.communicate()
    took = time.monotonic() - t0
    logs = "".join(f"\n--- {p}:\n{_tail(p, 10)}" for p in sorted(run_dir.glob("logs/*.log")))
    # Every way the contract is broken is listed at once, with the evidence.
    problems = []
    if proc.returncode != 2:
        problems.append(f"exit code {proc.returncode}, expected 2")
    if "Traceback" in out + err:
        problems.append("a traceback was printed")
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ln.startswith("swarm-up: error: ")]
    if len(lines) != 1:
        problems.append(f"{len(lines)} lines on stderr, expected exactly one")
    if len(errors) != 1:
        problems.append("no single 'swarm-up: error: ' line on stderr")
    line = errors[0] if errors else ""
    named = (flag, broken.name) if str(broken) in args else (flag,)  # contract: flag or file
    if not any(word in line for word in named):
        problems.append(f"the error line does not name {' or '.join(named)}")
    if args[:2] == ["--swarm-size", "500"] and not (
            "fit" in line and any(int(x) != 500 for x in re.findall(r"\d+", line))):
        problems.append("the error line does not say how many robots fit")
    if took > limit_s:
        problems.append(f"took {took:.1f} s, limit {limit_s} s")
    assert not problems, (f"{'; '.join(problems)}\ncommand: {' '.join(argv)}\n"
                          f"exit {proc.returncode} after {took:.1f} s\nstdout:\n{out}\n"
                          f"stderr:\n{err}{logs}")
