"""``swarm-bench``: sizes x runs of ``swarm-up`` -> table, JSON, plot, and the messaging baseline
(docs/reference/contract.md#s2, #s6).

For every size N and run r it starts, from this Python's ``bin/``::

    swarm-up --swarm-size N --world W --seed S+r --commanders --rtf 0 --duration D
             --metrics DIR/nN-r<r>.metrics.json --run-dir DIR/nN-r<r>
             [--coordination MODE] [--processes per-robot|K]

with this environment (``ROS_DOMAIN_ID`` ...), follows its progress lines, reads its metrics at
the end, and, with ``--baseline``, then runs the messaging baseline
(:mod:`swarm_bench.baseline`) for N robots in the process layout that run reported.  After
every finished run the JSON is written again, so an interrupted bench keeps the rows it finished.

The JSON (``--output``): ``command`` (the bench's argv), ``started``/``finished``, ``git``
(``commit``, ``dirty``), ``machine`` (``cores``, ``python``, ``rclpy``, ``platform``, ``rmw``,
``load_average_start``/``_end``), ``settings`` (the flags), ``run_dir``, ``interrupted``,
``exit_code``, ``records`` and ``summary``.  A swarm record: ``kind`` ``"swarm"``, ``size``,
``run``, ``seed``, ``command`` (swarm-up's argv), ``exit_code``, ``log``, ``error`` (the last
error line when the exit code is not 0), ``cpu_s``, ``cpu_source``, ``cpu_per_robot``,
``rss_mb_per_robot`` and ``metrics`` (swarm-up's ``--metrics`` file as it wrote it, None if it
wrote none).  A baseline record: ``kind`` ``"baseline"``, ``size``, ``command`` (the equivalent
``python -m swarm_bench.baseline run``), ``exit_code`` and ``baseline`` (its figures,
:func:`swarm_bench.baseline.run_baseline`).

Figures the bench adds to swarm-up's:

- ``cpu_per_robot`` [CPU s per robot per simulated s]: CPU time (user + system) of swarm-up and
  every process it started (simulator, navigators, commanders, groups; swarm-up's own metrics
  thread included), from the moment swarm-up reports every navigator ready to the moment it
  starts stopping, divided by robots x simulated seconds.  x1000 = the table's "ms"; x100 = the
  CPU % one robot needs at RTF 1.  Spawning and shutting down are left out.  Sampled with
  psutil every second (a process that exits keeps its last sample); ``cpu_source`` ``"bench"``.
  A run that ends before the bench could sample between those two moments (a few simulated
  seconds at a high RTF) takes swarm-up's own ``cpu_percent`` over its whole wall time instead,
  spawning included: ``cpu_source`` ``"swarm-up"``.
- ``rss_mb_per_robot`` [MB]: swarm-up's ``peak_rss_mb_per_robot`` (the peak of the summed RSS of
  the navigator, commander and group processes, divided by N; the simulator's is apart).
- baseline records: the baseline's ``rtf``, ``robot_ticks_per_s``, ``ticks``, ``late_ticks``,
  ``cpu_per_robot`` (the same definition over the baseline's processes), its layout.
- ``summary[i]`` per size: mean/min/max RTF over the runs that ended with exit 0, mean
  robot-ticks/s and throughput, mean goals and collisions per run, the smallest separation, and
  ``rtf_pct_of_baseline`` = 100 x mean RTF / baseline RTF.
- with ``--ledger``: ``ledger`` in each swarm record, the run's cost ledger over the same window
  as ``cpu_per_robot`` (:func:`swarm_bench.ledger.build_ledger`; None when py-spy took no
  sample), and in ``summary[i]`` the mean of the size's ledgers (:mod:`swarm_bench.ledger`).

Exit codes: 0 every run ended well, 1 a swarm-up or baseline run failed (recorded with its exit
code; the bench goes on), 2 bad flags (one line naming the flag), 130 interrupted (Ctrl-C or
SIGTERM: the current swarm-up gets SIGINT and is waited for; the finished rows are still
written, shown and plotted; the interrupted run is left out).
"""

from __future__ import annotations

import argparse
import contextlib
import datetime
import json
import logging
import math
import os
import platform
import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass, replace
from pathlib import Path

from swarm_common import cli
from swarm_common.errors import EXIT_OK, EXIT_RUNTIME, InputError, run_cli
from swarm_up.args import default_processes, default_run_dir, processes_arg
from swarm_up.run_config import PER_ROBOT
from swarm_up.supervisor import LogTail, StopFlag

PROG = "swarm-bench"
SCHEMA_VERSION = 1
TAIL_PERIOD_S = 0.2  # [s] wall between reads of a child's log
CPU_PERIOD_S = 1.0  # [s] wall between CPU samples
STOP_GRACE_S = 30.0  # [s] wall a swarm-up gets after SIGINT before SIGKILL
READY_RE = re.compile(r"all \d+ navigators ready")
PROGRESS_RE = re.compile(r"t = ([\d.]+)(?: / [\d.]+)? s simulated, RTF ([\d.]+)")
STOPPING_RE = re.compile(r"^swarm-up: stopping \(")


# ---------------------------------------------------------------------------------------- flags
def _sizes(text: str) -> tuple[int, ...]:
    what = f"must be a comma-separated list of positive integers, got {text!r}"
    parts = [p.strip() for p in text.split(",")]
    if not text.strip() or any(not p.isdigit() or int(p) <= 0 for p in parts):
        raise argparse.ArgumentTypeError(what)
    sizes = tuple(int(p) for p in parts)
    if len(set(sizes)) != len(sizes):
        raise argparse.ArgumentTypeError(f"lists a size twice: {text!r}")
    return sizes


def sweep_parser(prog: str, description: str, goes_on: str, kept: str,
                 sizes: tuple[int, ...], runs: int, runs_help: str) -> argparse.ArgumentParser:
    """The parser of a sweep of ``swarm-up`` runs, with the flags ``swarm-bench`` and
    ``swarm-experiment`` share: ``--sizes``, ``--duration``, ``--runs``, ``--world``, ``--seed``
    (defaults: ``sizes``, 300 s, ``runs``, slim_blockage, 0) and ``--processes`` (passed to
    swarm-up).

    Args:
        prog: the command.
        description: what it does.
        goes_on: what goes on after a failed run (its epilog: "the bench goes on").
        kept: what an interruption keeps ("rows").
        sizes: default ``--sizes``.
        runs: default ``--runs``.
        runs_help: ``--runs``' help.
    """
    p = cli.ArgumentParser(
        prog=prog, allow_abbrev=False, description=description,
        epilog=f"Exit codes: 0 success, 1 a run failed (the {goes_on} goes on), 2 bad input, "
        f"130 interrupted (the finished {kept} are kept).")
    p.add_argument("--sizes", type=_sizes, default=sizes, metavar="N,N,...",
                   help=f"swarm sizes (default: {','.join(map(str, sizes))})")
    p.add_argument("--duration", type=cli.positive_float, default=300.0, metavar="SEC",
                   help="simulated seconds per run (default: %(default)g)")
    p.add_argument("--runs", type=cli.positive_int, default=runs, metavar="R",
                   help=f"{runs_help} (default: %(default)s)")
    cli.add_shared(p, "--world", help="world (default: %(default)s)")
    cli.add_shared(p, "--seed", help="seed of the first run (default: %(default)s)")
    p.add_argument("--processes", type=processes_arg, default=None, metavar="per-robot|K",
                   help="passed to swarm-up (default: swarm-up's own choice per size)")
    return p


def build_parser() -> argparse.ArgumentParser:
    """The ``swarm-bench`` argument parser."""
    p = sweep_parser(
        PROG, "Benchmark the swarm: run swarm-up unpaced with commanders for every size (and "
        "run), then print a table and write JSON and a PNG plot; --baseline also measures the "
        "messaging baseline of every size.", "bench", "rows", (5, 20, 50, 100), 1,
        "runs per size; run r uses seed S+r")
    p.add_argument("--coordination", choices=("decentralized", "centralized"),
                   default="decentralized", help="passed to swarm-up (default: %(default)s)")
    p.add_argument("--output", type=Path, default=Path("bench.json"), metavar="PATH",
                   help="JSON results (default: %(default)s)")
    p.add_argument("--plot", type=Path, default=Path("bench.png"), metavar="PATH.png",
                   help="PNG plot (default: %(default)s)")
    p.add_argument("--baseline", "--floor", dest="baseline", action="store_true",
                   help="also measure the messaging baseline of every size")
    p.add_argument("--run-dir", type=Path, default=None, metavar="DIR",
                   help="logs and run directories (default: runs/bench-<timestamp>/)")
    p.add_argument("--swarm-up", type=Path, default=None, metavar="PATH",
                   help="the swarm-up executable to measure, e.g. another checkout's "
                   "venv/bin/swarm-up to compare versions (default: the one beside this Python)")
    p.add_argument("--ledger", action="store_true",
                   help="also profile every run with py-spy and report the cost ledger: CPU per "
                   "robot per simulated second by process role and stage (pip install -e "
                   "\".[ledger]\")")
    p.add_argument("--ledger-plot", type=Path, default=Path("ledger.png"), metavar="PATH.png",
                   help="the ledger's PNG chart, with --ledger (default: %(default)s)")
    p.add_argument("--ready-timeout", type=cli.positive_float, default=None, metavar="SEC",
                   help="passed to swarm-up: wall seconds to wait for every navigator to be "
                   "ready (default: swarm-up's; 1,000 robots take about 300 s here)")
    return p


@dataclass(frozen=True)
class BenchConfig:
    """The validated flags.

    Attributes:
        sizes: swarm sizes, in the order given.
        duration_s: simulated seconds per run [s].
        runs: runs per size.
        world: as given (swarm-up resolves it again).
        seed: seed of run 0 (run r: seed + r).
        coordination: passed through.
        processes: ``per-robot``, K, or None (swarm-up's default).
        output: JSON path.
        plot: PNG path.
        baseline: measure the baseline.
        run_dir: absolute directory of the logs and runs.
        swarm_up: the ``swarm-up`` executable measured (absolute).
        extra_args: more ``swarm-up`` flags for every run (``swarm-bench``'s
            ``--ready-timeout``, ``swarm-experiment``'s ``--faults SPEC``).
        py_spy: the ``py-spy`` executable with ``--ledger``, else None (no ledger).
        ledger_plot: the ledger's PNG with ``--ledger``.
    """

    sizes: tuple[int, ...]
    duration_s: float
    runs: int
    world: str
    seed: int
    coordination: str
    processes: str | int | None
    output: Path
    plot: Path
    baseline: bool
    run_dir: Path
    swarm_up: Path
    extra_args: tuple[str, ...] = ()
    py_spy: str | None = None
    ledger_plot: Path | None = None


def world_arg(world: str) -> str:
    """``--world``, checked: a world name as it is, a path made absolute (swarm-up runs in its
    run directory).

    Raises:
        InputError: no such world (the line names ``--world``).
    """
    from swarm_scene.world import resolve_world

    try:
        resolve_world(world)
    except InputError as exc:
        msg = str(exc)
        raise InputError(msg if msg.startswith("--world") else f"--world: {msg}") from None
    return str(Path(world).resolve()) if Path(world).is_file() else world


def _check_file_flag(flag: str, path: Path, suffix: str | None = None) -> Path:
    path = path.expanduser()
    if suffix is not None and path.suffix.lower() != suffix:
        raise InputError(f"{flag}: must be a {suffix} file, got '{path}'")
    if path.is_dir():
        raise InputError(f"{flag}: '{path}' is a directory")
    parent = path.resolve().parent
    if not parent.is_dir():
        raise InputError(f"{flag}: directory '{parent}' does not exist")
    return path.resolve()


def validate(args: argparse.Namespace) -> BenchConfig:
    """Check the flags that argparse cannot.

    Raises:
        InputError: the first bad flag (the one line shown, naming it).
    """
    world = world_arg(args.world)
    output = _check_file_flag("--output", args.output)
    plot = _check_file_flag("--plot", args.plot, ".png")
    if args.run_dir is not None and args.run_dir.exists() and not args.run_dir.is_dir():
        raise InputError(f"--run-dir: '{args.run_dir}' exists and is not a directory")
    run_dir = args.run_dir or default_run_dir(prefix="bench-")
    py_spy = ledger_plot = None
    if args.ledger:
        from swarm_bench.ledger import py_spy_path

        py_spy = py_spy_path()
        ledger_plot = _check_file_flag("--ledger-plot", args.ledger_plot, ".png")
    return BenchConfig(
        sizes=args.sizes, duration_s=args.duration, runs=args.runs, world=world,
        seed=args.seed, coordination=args.coordination, processes=args.processes,
        output=output, plot=plot, baseline=args.baseline, run_dir=run_dir.expanduser().resolve(),
        swarm_up=swarm_up_path(args.swarm_up), py_spy=py_spy, ledger_plot=ledger_plot,
        extra_args=(() if args.ready_timeout is None
                    else ("--ready-timeout", f"{args.ready_timeout:g}")))


# -------------------------------------------------------------------------------------- context
def git_commit() -> dict:
    """``{"commit": sha or None, "dirty": bool or None, "diff_sha256": hex or None}`` of the
    code's repository: ``dirty`` when a tracked file differs from the commit, and then the
    SHA-256 of ``git diff HEAD --binary`` (the changes the runs were made with, to tell two
    dirty trees apart)."""
    import hashlib

    from swarm_common import paths

    def git(*args: str, strip: bool = True) -> str | None:
        try:
            res = subprocess.run(["git", "-C", str(paths.ROOT), *args], capture_output=True,
                                 text=True, timeout=30)
        except (OSError, subprocess.TimeoutExpired):
            return None
        if res.returncode != 0:
            return None
        return res.stdout.strip() if strip else res.stdout

    sha = git("rev-parse", "HEAD")
    status = git("status", "--porcelain", "--untracked-files=no") if sha else None
    dirty = None if status is None else bool(status)
    diff = git("diff", "HEAD", "--binary", strip=False) if dirty else None
    return {"commit": sha, "dirty": dirty,
            "diff_sha256": None if diff is None else hashlib.sha256(diff.encode()).hexdigest()}


def machine_info() -> dict:
    """Cores, CPU model, Python, ROS 2 distribution (``ROS_DISTRO``, else ``jazzy`` for the
    ``ros-jazzy-rclpy`` wheels), rclpy and Fast DDS versions, platform, RMW, and the load
    average now."""
    from importlib import metadata

    def version(*dists: str) -> str | None:
        for dist in dists:
            try:
                return metadata.version(dist)
            except metadata.PackageNotFoundError:
                continue
        return None

    rclpy_version = version("ros-jazzy-rclpy", "rclpy")
    fastdds = version("ros-fastrtps", "fastdds")
    cpu_model = None
    try:
        with open("/proc/cpuinfo") as f:
            cpu_model = next((line.split(":", 1)[1].strip() for line in f
                              if line.startswith("model name")), None)
    except OSError:
        pass
    return {
        "cores": os.cpu_count(),
        "cpu_model": cpu_model or platform.processor() or None,
        "python": platform.python_version(),
        "ros_distro": os.environ.get("ROS_DISTRO") or ("jazzy" if rclpy_version else None),
        "rclpy": rclpy_version,
        "fastdds": fastdds,
        "platform": platform.platform(),
        "rmw": os.environ.get("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp (default)"),
        "load_average_start": [round(x, 2) for x in os.getloadavg()],
    }


# -------------------------------------------------------------------------------------- display
class BenchView:
    """Progress: a rich progress bar per run on a terminal, else plain lines.

    Args:
        tty: draw bars (True) or print lines (False).
        prog: the prefix of plain lines (the command's name).
    """

    def __init__(self, tty: bool, prog: str = PROG):
        self._prog = prog
        self._progress = None
        self._task = None
        self._label = ""
        if tty:
            from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

            self._progress = Progress(
                TextColumn("{task.description:<24}"), BarColumn(),
                TextColumn("{task.completed:>5.0f}/{task.total:.0f} s sim"),
                TextColumn("RTF {task.fields[rtf]}"), TimeElapsedColumn())
            self._progress.start()

    def say(self, line: str) -> None:
        """One line above the bars (or on stdout)."""
        if self._progress is not None:
            self._progress.console.print(line, markup=False, highlight=False)
        else:
            print(f"{self._prog}: {line}", flush=True)

    def start(self, label: str, total_s: float) -> None:
        """A new run: ``label`` (size, run), ``total_s`` simulated seconds."""
        self._label = label
        if self._progress is not None:
            self._task = self._progress.add_task(label, total=total_s, rtf="-")
        else:
            self.say(f"{label}: starting")

    def update(self, sim_s: float, rtf: float | None) -> None:
        """Simulated time reached and RTF so far."""
        text = "-" if rtf is None else f"{rtf:.2f}"
        if self._progress is not None and self._task is not None:
            self._progress.update(self._task, completed=sim_s, rtf=text)
        elif self._progress is None:
            self.say(f"{self._label}: t = {sim_s:.0f} s simulated, RTF {text}")

    def finish(self, line: str, sim_s: float | None = None, rtf: float | None = None) -> None:
        """End the current run with a line (and its final simulated time and RTF)."""
        if self._progress is not None and self._task is not None:
            if sim_s is not None:
                self._progress.update(self._task, completed=sim_s,
                                      rtf="-" if rtf is None else f"{rtf:.2f}")
            self._progress.stop_task(self._task)
            self._task = None
        self.say(line)

    def close(self) -> None:
        """Stop drawing (idempotent)."""
        if self._progress is not None:
            self._progress.stop()
            self._progress = None


# ------------------------------------------------------------------------------------------ runs
def swarm_up_path(given: Path | None = None) -> Path:
    """The ``swarm-up`` to measure: ``given`` (``--swarm-up``), else the one beside this Python.

    Raises:
        InputError: it is not an executable file.
    """
    if given is not None:
        path = given.expanduser().resolve()
        if not (path.is_file() and os.access(path, os.X_OK)):
            raise InputError(f"--swarm-up: '{given}' is not an executable file")
        return path
    path = Path(sys.executable).parent / "swarm-up"
    if not path.is_file():
        raise InputError(f"swarm-up: not installed beside {sys.executable} "
                         "(pip install -e . in this venv)")
    return path


def swarm_up_command(cfg: BenchConfig, n: int, seed: int, run_dir: Path,
                     metrics: Path) -> list[str]:
    """The ``swarm-up`` command line of one run."""
    argv = [str(cfg.swarm_up), "--swarm-size", str(n), "--world", cfg.world,
            "--seed", str(seed), "--commanders", "--rtf", "0", "--duration", f"{cfg.duration_s:g}",
            "--metrics", str(metrics), "--run-dir", str(run_dir),
            "--coordination", cfg.coordination]
    if cfg.processes is not None:
        argv += ["--processes", str(cfg.processes)]
    return argv + list(cfg.extra_args)


def _error_line(log: Path) -> str:
    try:
        lines = log.read_text(errors="replace").splitlines()
    except OSError:
        return ""
    errors = [ln.strip() for ln in lines if "error:" in ln]
    return errors[-1] if errors else (lines[-1].strip() if lines else "")


def _follow_run(proc: subprocess.Popen, log_path: Path, stop: StopFlag, view: BenchView,
                cpu, profiler=None) -> tuple[int, bool, float | None]:
    """Follow a ``swarm-up`` process to its end: its progress to ``view``, the CPU time of its
    process tree from every robot ready to the stop (sampled every ``CPU_PERIOD_S`` into
    ``cpu``, a :class:`~swarm_bench.proc_cpu.TreeCpu` of it), the profiler (a
    :class:`~swarm_bench.ledger.Profiler`) over the same window, SIGINT when ``stop`` is set
    (SIGKILL ``STOP_GRACE_S`` later).

    Returns:
        ``(exit code, interrupted, CPU seconds from ready to stopping or None)``.
    """
    tail = LogTail(log_path)
    stopping = interrupted = False
    signalled_at: float | None = None
    last_cpu = 0.0
    while True:
        code = proc.poll()
        for line in tail.lines():
            if READY_RE.search(line) and not cpu.marked:
                cpu.mark()
                if profiler is not None:
                    profiler.start(proc.pid)
            elif STOPPING_RE.search(line) and not stopping:
                stopping = True
                if cpu.marked:
                    cpu.sample()
                if profiler is not None:
                    profiler.stop()
            m = PROGRESS_RE.search(line)
            if m:
                view.update(float(m.group(1)), float(m.group(2)))
        if code is not None:
            return code, interrupted, cpu.since_mark() if stopping else None
        now = time.monotonic()
        if stop and signalled_at is None:
            interrupted, signalled_at = True, now
            proc.send_signal(signal.SIGINT)
        elif signalled_at is not None and now - signalled_at > STOP_GRACE_S:
            proc.kill()
        if cpu.marked and not stopping and now - last_cpu >= CPU_PERIOD_S:
            last_cpu = now
            cpu.sample()
        time.sleep(TAIL_PERIOD_S)


def run_swarm_up(cfg: BenchConfig, n: int, r: int, stop: StopFlag, view: BenchView) -> dict:
    """One ``swarm-up`` run, followed to its end.

    Returns:
        The record (see the module doc); ``interrupted`` True if ``stop`` was set meanwhile.
    """
    name = f"n{n}-r{r}"
    seed = cfg.seed + r
    metrics_path = cfg.run_dir / f"{name}.metrics.json"
    metrics_path.unlink(missing_ok=True)
    log_path = cfg.run_dir / f"{name}.log"
    argv = swarm_up_command(cfg, n, seed, cfg.run_dir / name, metrics_path)
    view.start(f"size {n}, run {r + 1}/{cfg.runs}", cfg.duration_s)
    (cfg.run_dir / name).mkdir(parents=True, exist_ok=True)
    with open(log_path, "wb") as log:
        # cwd: the run's own directory, so that the ``python -m`` children of a swarm-up from
        # another checkout (--swarm-up) cannot import this checkout's packages from the cwd.
        try:
            proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                    cwd=cfg.run_dir / name, env=dict(os.environ),
                                    start_new_session=True)
        except OSError as exc:
            raise InputError(f"--swarm-up: cannot run '{argv[0]}': {exc.strerror}") from None
    from swarm_bench.proc_cpu import TreeCpu

    cpu, profiler = TreeCpu([proc.pid]), None
    if cfg.py_spy is not None:
        from swarm_bench.ledger import Profiler

        profiler = Profiler(cfg.py_spy, cfg.run_dir / f"{name}.pyspy.raw")
    code, interrupted, cpu_s = _follow_run(proc, log_path, stop, view, cpu, profiler)
    try:
        metrics = json.loads(metrics_path.read_text())
    except (OSError, ValueError):
        metrics = None
    metrics = metrics if isinstance(metrics, dict) else None
    sim_s = _num(metrics, "sim_time_s")
    cpu_source = "bench"
    if not cpu_s:  # the run ended within one poll: no sample fell between ready and stopping
        cpu_pct, wall = _num(metrics, "cpu_percent"), _num(metrics, "orchestrator_wall_time_s")
        cpu_s = cpu_pct / 100.0 * wall if cpu_pct and wall else None
        cpu_source = "swarm-up" if cpu_s else None
    record = {
        "kind": "swarm",
        "size": n,
        "run": r,
        "seed": seed,
        "command": argv,
        "exit_code": code,
        "interrupted": interrupted,
        "log": str(log_path),
        "error": _error_line(log_path) if code != EXIT_OK else None,
        "cpu_s": cpu_s,
        "cpu_source": cpu_source,
        "cpu_per_robot": (cpu_s / (n * sim_s)) if cpu_s is not None and sim_s else None,
        "rss_mb_per_robot": _num(metrics, "peak_rss_mb_per_robot"),
        "metrics": metrics,
    }
    if profiler is not None:
        record["ledger"] = _ledger(profiler, cpu, n, sim_s, cpu_source)
    if code == EXIT_OK and metrics is not None:
        view.finish(f"size {n}, run {r + 1}/{cfg.runs}: RTF {_fmt(metrics.get('rtf'))}, "
                    f"{_fmt(metrics.get('robot_ticks_per_s'), 0)} robot-ticks/s, "
                    f"goals reached {metrics.get('goals_reached')}", sim_s, _num(metrics, "rtf"))
    else:
        why = "" if interrupted else f" ({record['error']})"
        view.finish(f"size {n}, run {r + 1}/{cfg.runs}: swarm-up exited with code {code}{why}; "
                    f"log: {log_path}")
    return record


def _ledger(profiler, cpu, n: int, sim_s: float | None, cpu_source: str | None) -> dict | None:
    """A run's cost ledger (:func:`swarm_bench.ledger.build_ledger`), None when the window was
    not measured (the run failed, or ended before a CPU sample) or py-spy wrote no sample."""
    from swarm_bench.ledger import build_ledger, role_of

    samples = profiler.stop()
    if not samples or not sim_s or cpu_source != "bench":
        return None
    roles = {pid: role_of(line) for pid, line in cpu.cmdlines.items()}
    return build_ledger(samples, cpu.by_pid_since_mark(), roles, n, sim_s)


def run_baseline_size(cfg: BenchConfig, base, n: int, processes: str | int, stop: StopFlag,
                      view: BenchView) -> dict:
    """The baseline for ``n`` robots in ``processes`` layout.

    Returns:
        The baseline record (see the module doc).
    """
    from swarm_bench.baseline import PROG as BASELINE_PROG
    from swarm_bench.baseline import run_baseline

    run_dir = cfg.run_dir / f"baseline-n{n}"
    run_dir.mkdir(parents=True, exist_ok=True)
    bcfg = replace(base, robots=tuple(f"Srobot{i}" for i in range(1, n + 1)),
                   summary_path=str(run_dir / "baseline_summary.json"))
    view.start(f"baseline, size {n}", cfg.duration_s)
    figures = run_baseline(bcfg, processes, run_dir, should_stop=lambda: bool(stop),
                           on_progress=view.update)
    command = [sys.executable, "-m", BASELINE_PROG, "run", "--swarm-size", str(n), "--duration",
               f"{cfg.duration_s:g}", "--processes", str(processes), "--world", cfg.world]
    ok = figures["exit_code"] == EXIT_OK and not figures["interrupted"]
    view.finish(f"baseline, size {n}: RTF {_fmt(figures.get('rtf'))}, "
                f"{_fmt(figures.get('robot_ticks_per_s'), 0)} robot-ticks/s" if ok else
                f"baseline, size {n}: ended with code {figures['exit_code']}; logs: "
                f"{figures['logs']}", figures.get("sim_time_s"), figures.get("rtf"))
    return {"kind": "baseline", "size": n, "command": command, "exit_code": figures["exit_code"],
            "interrupted": bool(stop), "baseline": figures}


# ---------------------------------------------------------------------------------------- report
def _num(d: dict | None, key: str) -> float | None:
    if not isinstance(d, dict):
        return None
    value = d.get(key)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return None
    return float(value) if math.isfinite(value) else None


def _mean(values: list[float]) -> float | None:
    return sum(values) / len(values) if values else None


def summarize(sizes: tuple[int, ...], records: list[dict]) -> list[dict]:
    """One summary per size that has a finished record (see the module doc)."""
    out = []
    for n in sizes:
        runs = [r for r in records if r["kind"] == "swarm" and r["size"] == n]
        baselines = [r for r in records if r["kind"] == "baseline" and r["size"] == n]
        if not runs and not baselines:
            continue
        ok = [r for r in runs if r["exit_code"] == EXIT_OK and r["metrics"]]

        def values(key, rows=ok):
            return [v for v in (_num(r["metrics"], key) for r in rows) if v is not None]

        def col(key, sub, rows=ok):
            return [v for v in (_num((r["metrics"] or {}).get(key), sub) for r in rows)
                    if v is not None]

        rtf = values("rtf")
        baseline = baselines[-1]["baseline"] if baselines else None
        baseline_ok = bool(baselines) and baselines[-1]["exit_code"] == EXIT_OK
        baseline_rtf = _num(baseline, "rtf") if baseline_ok else None
        seps = values("min_separation_m")
        entry = {
            "size": n,
            "runs": len(runs),
            "runs_ok": len(ok),
            "rtf_mean": _mean(rtf),
            "rtf_min": min(rtf) if rtf else None,
            "rtf_max": max(rtf) if rtf else None,
            "robot_ticks_per_s_mean": _mean(values("robot_ticks_per_s")),
            "throughput_per_hour_mean": _mean(values("throughput_per_hour")),
            "goals_reached_mean": _mean(values("goals_reached")),
            "goals_aborted_mean": _mean(values("goals_aborted")),
            "collisions_robot_robot_mean": _mean(col("collisions", "robot_robot")),
            "collisions_robot_wall_mean": _mean(col("collisions", "robot_wall")),
            "min_separation_m": min(seps) if seps else None,
            "cpu_per_robot_mean": _mean([r["cpu_per_robot"] for r in ok
                                         if r["cpu_per_robot"] is not None]),
            "rss_mb_per_robot_mean": _mean([r["rss_mb_per_robot"] for r in ok
                                            if r["rss_mb_per_robot"] is not None]),
            "processes": ok[0]["metrics"].get("processes") if ok else None,
            "baseline_rtf": baseline_rtf,
            "baseline_robot_ticks_per_s": (_num(baseline, "robot_ticks_per_s")
                                           if baseline_rtf else None),
            "baseline_cpu_per_robot": _num(baseline, "cpu_per_robot") if baseline_rtf else None,
            "rtf_pct_of_baseline": (100.0 * _mean(rtf) / baseline_rtf
                                 if rtf and baseline_rtf else None),
        }
        ledgers = [r["ledger"] for r in ok if r.get("ledger")]
        if ledgers:
            from swarm_bench.ledger import mean_ledger

            entry["ledger"] = mean_ledger(ledgers)
        out.append(entry)
    return out


def _fmt(value, digits: int = 2, scale: float = 1.0) -> str:
    if value is None or isinstance(value, bool):
        return "-"
    if isinstance(value, int) and scale == 1.0:
        return str(value)
    try:
        return f"{float(value) * scale:.{digits}f}"
    except (TypeError, ValueError):
        return str(value)


def print_table(summary: list[dict], with_baseline: bool, title: str) -> None:
    """The bench table (rich; plain text when not a terminal)."""
    from rich import box
    from rich.console import Console
    from rich.markup import escape
    from rich.table import Table

    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False)
    heads = ["size", "runs", "RTF", "robot-\nticks/s", "tasks/h", "goals\nok/abort",
             "collisions\nrobot/wall", "min sep\n[m]", "CPU/robot\n[ms/sim s]",
             "RSS/robot\n[MB]"]
    if with_baseline:
        heads += ["baseline\nRTF", "% of\nbaseline"]
    for h in heads:
        table.add_column(escape(h), justify="right", overflow="fold")
    for s in summary:
        d = 0 if s["runs_ok"] <= 1 else 1
        rtf = _fmt(s["rtf_mean"])
        if s["runs_ok"] > 1:
            rtf += f" ({_fmt(s['rtf_min'])}-{_fmt(s['rtf_max'])})"
        row = [str(s["size"]), f"{s['runs_ok']}/{s['runs']}", rtf,
               _fmt(s["robot_ticks_per_s_mean"], 0), _fmt(s["throughput_per_hour_mean"], 1),
               f"{_fmt(s['goals_reached_mean'], d)} / {_fmt(s['goals_aborted_mean'], d)}",
               f"{_fmt(s['collisions_robot_robot_mean'], d)} / "
               f"{_fmt(s['collisions_robot_wall_mean'], d)}",
               _fmt(s["min_separation_m"], 3), _fmt(s["cpu_per_robot_mean"], 1, 1000.0),
               _fmt(s["rss_mb_per_robot_mean"], 1)]
        if with_baseline:
            row += [_fmt(s["baseline_rtf"]), _fmt(s["rtf_pct_of_baseline"], 0)]
        table.add_row(*row)
    # Off a terminal rich would fold the table into 80 columns: give it room instead.
    Console(width=None if sys.stdout.isatty() else 160).print(table)


def write_plot(path: Path, summary: list[dict], title: str) -> None:
    """RTF, robot-ticks/s and throughput against swarm size (PNG, matplotlib's Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = sorted(summary, key=lambda s: s["size"])
    fig, axes = plt.subplots(1, 3, figsize=(15, 4.5), constrained_layout=True)
    panels = (("rtf_mean", "real-time factor", "baseline_rtf"),
              ("robot_ticks_per_s_mean", "robot-ticks per wall second",
               "baseline_robot_ticks_per_s"),
              ("throughput_per_hour_mean", "throughput [tasks per simulated hour]", None))
    for ax, (key, label, baseline_key) in zip(axes, panels, strict=True):
        pts = [(s["size"], s[key]) for s in rows if s[key] is not None]
        if pts:
            xs, ys = zip(*pts, strict=True)
            if key == "rtf_mean":
                lo = [s["rtf_mean"] - s["rtf_min"] for s in rows if s[key] is not None]
                hi = [s["rtf_max"] - s["rtf_mean"] for s in rows if s[key] is not None]
                ax.errorbar(xs, ys, yerr=[lo, hi], marker="o", capsize=3, label="swarm-up")
            else:
                ax.plot(xs, ys, marker="o", label="swarm-up")
        if baseline_key is not None:
            fpts = [(s["size"], s[baseline_key]) for s in rows if s[baseline_key] is not None]
            if fpts:
                fx, fy = zip(*fpts, strict=True)
                ax.plot(fx, fy, marker="s", linestyle="--", label="messaging baseline")
        if key == "rtf_mean":
            ax.axhline(1.0, color="grey", linewidth=0.8)
        ax.set_xticks([s["size"] for s in rows])
        ax.set_xlabel("swarm size [robots]")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
        if ax.get_legend_handles_labels()[0]:
            ax.legend()
    fig.suptitle(title)
    fig.savefig(path, format="png", dpi=100)
    plt.close(fig)


def _write_json(path: Path, doc: dict) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(doc, indent=2, default=str) + "\n")
    os.replace(tmp, path)


# ------------------------------------------------------- shared by swarm-bench, swarm-experiment
def _now() -> str:
    return datetime.datetime.now().astimezone().isoformat(timespec="seconds")


def new_doc(kind: str, prog: str, schema_version: int, argv: list[str], settings: dict,
            **extra) -> dict:
    """The JSON document of a bench or an experiment before its first run: ``{kind: prog}``,
    ``schema_version``, ``command``, ``started``, ``git``, ``machine``, ``settings``, ``extra``,
    and the run's outcome (``finished``, ``interrupted``, ``exit_code``, ``records``,
    ``summary``) still empty."""
    return {kind: prog, "schema_version": schema_version, "command": [prog, *argv],
            "started": _now(), "finished": None, "git": git_commit(), "machine": machine_info(),
            "settings": settings, **extra, "interrupted": False, "exit_code": None,
            "records": [], "summary": []}


@contextlib.contextmanager
def stop_on_signals() -> Iterator[StopFlag]:
    """A :class:`StopFlag` that SIGINT and SIGTERM set while the block runs (the handlers
    before it are restored after)."""
    stop = StopFlag()
    old = {s: signal.signal(s, stop) for s in (signal.SIGINT, signal.SIGTERM)}
    try:
        yield stop
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)


def finish_doc(doc: dict, path: Path, summary: list[dict], stop: StopFlag, failed: bool) -> int:
    """Close the document (outcome, end time, the machine's load, ``summary``) and write it to
    ``path``.

    Returns:
        The exit code: 130 interrupted, 1 a run failed, else 0.
    """
    code = 130 if stop else (EXIT_RUNTIME if failed else EXIT_OK)
    doc.update(interrupted=bool(stop), exit_code=code, finished=_now())
    doc["machine"]["load_average_end"] = [round(x, 2) for x in os.getloadavg()]
    doc["summary"] = summary
    _write_json(path, doc)
    return code


def say_outcome(prog: str, stop: StopFlag, failed: bool, kept: str, results: Path) -> None:
    """On stderr: the interruption (``kept``: what was kept) or that a run failed."""
    if stop:
        print(f"{prog}: interrupted; kept the {kept}", file=sys.stderr, flush=True)
    elif failed:
        print(f"{prog}: error: a run failed (see its exit code and log in {results})",
              file=sys.stderr, flush=True)


def command_main(prog: str, argv: list[str] | None, parse_and_check, run) -> int:
    """A measuring command's entry point: ``run(parse_and_check(args), args)`` under
    :func:`~swarm_common.errors.run_cli` (exit 2 on bad input)."""
    args = list(sys.argv[1:] if argv is None else argv)
    return run_cli(prog, lambda: run(parse_and_check(args), args))


# ------------------------------------------------------------------------------------------ main
def bench(cfg: BenchConfig, argv: list[str]) -> int:
    """Run the whole bench; returns the exit code (0, 1 or 130)."""
    cfg.run_dir.mkdir(parents=True, exist_ok=True)
    base_baseline = None
    if cfg.baseline:
        from swarm_bench.baseline import make_config

        quiet = logging.getLogger("swarm_scene")
        level = quiet.level
        quiet.setLevel(logging.ERROR)  # the robot's missing meshes: swarm-up warns about them
        try:
            base_baseline = make_config(1, cfg.duration_s, cfg.run_dir, world=cfg.world)
        finally:
            quiet.setLevel(level)
    settings = {k: (str(v) if isinstance(v, Path) else v) for k, v in asdict(cfg).items()}
    doc = new_doc("bench", PROG, SCHEMA_VERSION, argv, settings, run_dir=str(cfg.run_dir))
    title = (f"swarm-bench: {cfg.world}, {cfg.duration_s:g} simulated s, commanders, "
             f"{os.cpu_count()} cores")
    with stop_on_signals() as stop:
        view = BenchView(tty=sys.stdout.isatty())
        view.say(f"{len(cfg.sizes)} sizes x {cfg.runs} runs of {cfg.duration_s:g} simulated s"
                 f"{' and the baseline' if cfg.baseline else ''}; logs in {cfg.run_dir}")
        try:
            _bench_sizes(cfg, base_baseline, doc, stop, view)
        finally:
            view.close()
        failed = any(r["exit_code"] != EXIT_OK for r in doc["records"])
    code = finish_doc(doc, cfg.output, summarize(cfg.sizes, doc["records"]), stop, failed)
    print_table(doc["summary"], cfg.baseline, title)
    write_plot(cfg.plot, doc["summary"], title)
    print(f"{PROG}: results: {cfg.output}", flush=True)
    print(f"{PROG}: plot: {cfg.plot}", flush=True)
    if cfg.py_spy is not None:
        from swarm_bench.ledger import print_ledger, write_ledger_plot

        ledger_title = f"cost ledger: {cfg.world}, {cfg.duration_s:g} simulated s, commanders"
        print_ledger(doc["summary"], ledger_title)
        write_ledger_plot(cfg.ledger_plot, doc["summary"], ledger_title)
        print(f"{PROG}: ledger plot: {cfg.ledger_plot}", flush=True)
    say_outcome(PROG, stop, failed, f"{len(doc['records'])} finished records", cfg.output)
    return code


def _bench_sizes(cfg: BenchConfig, base_baseline, doc: dict, stop: StopFlag,
                 view: BenchView) -> None:
    """Every size's runs (and baseline), each record added to ``doc`` and written at once."""
    for n in cfg.sizes:
        runs = []
        for r in range(cfg.runs):
            if stop:
                break
            rec = run_swarm_up(cfg, n, r, stop, view)
            if rec["interrupted"]:
                break
            runs.append(rec)
            doc["records"].append(rec)
            doc["summary"] = summarize(cfg.sizes, doc["records"])
            _write_json(cfg.output, doc)
        if cfg.baseline and not stop:
            layout = cfg.processes
            if layout is None:
                reported = [r["metrics"].get("processes") for r in runs if r["metrics"]]
                layout = next((p for p in reported if p == PER_ROBOT
                               or (isinstance(p, int) and p > 0)), None)
                layout = layout if layout is not None else default_processes(n)
            rec = run_baseline_size(cfg, base_baseline, n, layout, stop, view)
            if not rec["interrupted"]:
                doc["records"].append(rec)
                doc["summary"] = summarize(cfg.sizes, doc["records"])
                _write_json(cfg.output, doc)
        if stop:
            break


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``swarm-bench``; returns the exit code (0, 1, 2 or 130)."""
    return command_main(PROG, argv, lambda args: validate(build_parser().parse_args(args)), bench)


if __name__ == "__main__":
    sys.exit(main())
