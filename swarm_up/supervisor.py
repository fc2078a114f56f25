"""Start, watch, restart and stop a run's children (docs/reference/contract.md#s5-supervision).

Every child runs in its own session (``setsid``), so it is its own process group: a signal sent
to the group reaches the child and anything it started, and the terminal's Ctrl-C reaches only
the orchestrator, which then stops the children in order.  Each child's stdout and stderr go to
one log file, ``RUN/logs/<name>.log``; a restart appends to the same file after a marker line.

Restart policy: a child with ``restart=True`` (navigators, commanders, groups) that exits with
any code other than 0 (done) or 2 (bad input, which a restart would not fix) is started again
on the next :meth:`Supervisor.poll` (the caller polls at >= 5 Hz, so within 2 s).  A child that
crashes ``max_fast_crashes`` times in a row, each within ``fast_crash_s`` of its start, is given
up on.  A child with ``restart=False`` (the simulator) is reported to the caller, who decides.

Stopping (:meth:`Supervisor.stop`): SIGINT to every group, then SIGTERM to what is left after
``sigint_grace_s``, then SIGKILL after ``sigterm_grace_s``; it returns within their sum plus
``kill_grace_s`` (5 s by default in total).
"""

from __future__ import annotations

import os
import signal
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import psutil

NO_RESTART_CODES = (0, 2)


@dataclass(frozen=True)
class ChildSpec:
    """What to run for one supervised process.

    Attributes:
        name: unique short name, also the log's stem (``sim``, ``nav_Srobot3``, ``group_1``).
        argv: the command line.
        log_path: file that receives stdout and stderr (appended to).
        kind: ``sim`` | ``coord`` | ``nav`` | ``cmd`` | ``group`` | ``record`` (used for per-robot
            accounting: the simulator, the coordinator and the recorder are not robots).
        robots: namespaces (without ``/``) this process serves.
        restart: restart it when it crashes (False: report its exit to the caller).
        env: environment (None: inherit the orchestrator's).
    """

    name: str
    argv: tuple[str, ...]
    log_path: Path
    kind: str = "nav"
    robots: tuple[str, ...] = ()
    restart: bool = True
    env: dict[str, str] | None = None


@dataclass
class ChildState:
    """Run-time state of one supervised child."""

    spec: ChildSpec
    proc: subprocess.Popen | None = None
    started_at: float = 0.0  # [s] time.monotonic() of the last start
    starts: int = 0
    restarts: int = 0
    fast_crashes: int = 0
    exit_code: int | None = None  # last exit code, once it exited and was not restarted
    given_up: bool = False
    retired: bool = False  # killed on purpose (a fault) and not to be restarted by poll
    planned: bool = False  # killed on purpose (a fault) and restarted by poll: not a crash


@dataclass(frozen=True)
class ChildExit:
    """A child exit seen by :meth:`Supervisor.poll`.

    Attributes:
        name: the child's name.
        code: its exit code (negative: killed by that signal).
        restarted: whether it was started again.
        gave_up: whether it will not be restarted any more because it crashed too often.
        planned: it was killed on purpose (:meth:`Supervisor.kill`, a fault), not a crash.
    """

    name: str
    code: int
    restarted: bool
    gave_up: bool = False
    planned: bool = False


@dataclass
class Supervisor:
    """Supervises the children of one run.

    Args:
        sigint_grace_s: wait after SIGINT before SIGTERM [s].
        sigterm_grace_s: wait after SIGTERM before SIGKILL [s].
        kill_grace_s: wait after SIGKILL [s].
        fast_crash_s: a crash within this time of the start counts as fast [s].
        max_fast_crashes: consecutive fast crashes after which a child is given up on.
        on_restart: called with the :class:`ChildExit` of every restart (for console output).
    """

    sigint_grace_s: float = 2.5
    sigterm_grace_s: float = 1.5
    kill_grace_s: float = 0.8
    fast_crash_s: float = 5.0
    max_fast_crashes: int = 5
    on_restart: Callable[[ChildExit], None] | None = None
    children: dict[str, ChildState] = field(default_factory=dict)
    stopping: bool = False

    # ------------------------------------------------------------------ start
    def start(self, spec: ChildSpec) -> ChildState:
        """Start a new child (its name must be unique).

        Args:
            spec: what to run.

        Returns:
            Its state record.

        Raises:
            ValueError: a child of that name exists.
            OSError: the command could not be started.
        """
        if spec.name in self.children:
            raise ValueError(f"child {spec.name!r} already supervised")
        state = ChildState(spec=spec)
        self.children[spec.name] = state
        self._launch(state)
        return state

    def _launch(self, state: ChildState) -> None:
        spec = state.spec
        spec.log_path.parent.mkdir(parents=True, exist_ok=True)
        with open(spec.log_path, "ab") as log:
            if state.starts:
                log.write(
                    f"\n--- swarm-up: restart {state.restarts} of {spec.name} at "
                    f"{time.strftime('%H:%M:%S')} ---\n".encode()
                )
                log.flush()
            state.proc = subprocess.Popen(
                list(spec.argv),
                stdin=subprocess.DEVNULL,
                stdout=log,
                stderr=subprocess.STDOUT,
                env=spec.env,
                start_new_session=True,
                close_fds=True,
            )
        state.started_at = time.monotonic()
        state.starts += 1
        state.exit_code = None

    # ------------------------------------------------------------------ watch
    def poll(self) -> list[ChildExit]:
        """Reap exited children and restart the restartable ones at once.

        Returns:
            One :class:`ChildExit` per child that exited since the last poll.
        """
        exits: list[ChildExit] = []
        for state in self.children.values():
            proc = state.proc
            if proc is None or state.exit_code is not None:
                continue
            code = proc.poll()
            if code is None:
                continue
            state.exit_code = code
            spec = state.spec
            planned, state.planned = state.planned, False
            if self.stopping or not spec.restart or code in NO_RESTART_CODES:
                exits.append(ChildExit(spec.name, code, restarted=False, planned=planned))
                continue
            lived = time.monotonic() - state.started_at
            state.fast_crashes = state.fast_crashes + 1 if lived < self.fast_crash_s else 0
            if state.fast_crashes >= self.max_fast_crashes:
                state.given_up = True
                exits.append(ChildExit(spec.name, code, restarted=False, gave_up=True))
                continue
            state.restarts += 1
            try:
                self._launch(state)
            except OSError:
                state.given_up = True
                exits.append(ChildExit(spec.name, code, restarted=False, gave_up=True))
                continue
            event = ChildExit(spec.name, code, restarted=True, planned=planned)
            exits.append(event)
            if self.on_restart is not None:
                self.on_restart(event)
        return exits

    @property
    def restarts(self) -> int:
        """Total restarts of all children so far."""
        return sum(s.restarts for s in self.children.values())

    def kill(self, name: str, restart: bool, wait_s: float = 2.0) -> int | None:
        """Kill a child at once (SIGKILL to its process group), as a crash would (fault
        injection, :mod:`swarm_up.faults`), and wait for it to exit.

        Args:
            name: the child.
            restart: True: the next :meth:`poll` sees the crash and restarts it as any other
                (a restart, counted); False: it is retired, not restarted (see :meth:`revive`).
            wait_s: how long to wait for it to exit [s].

        Returns:
            Its exit code, or None if it was not running or did not exit in time.
        """
        state = self.children.get(name)
        if state is None or state.proc is None or state.exit_code is not None:
            return None
        if not restart:
            state.retired = True
        state.planned = restart
        try:
            os.killpg(state.proc.pid, signal.SIGKILL)
        except (ProcessLookupError, PermissionError):
            pass
        try:
            code = state.proc.wait(wait_s)
        except subprocess.TimeoutExpired:
            return None
        if not restart:
            state.exit_code = code
        return code

    def revive(self, name: str) -> bool:
        """Start a retired child again (a restart, counted).

        Returns:
            Whether it was started.
        """
        state = self.children.get(name)
        if state is None or self.stopping or (state.proc is not None
                                              and state.proc.poll() is None):
            return False
        state.retired = False
        state.restarts += 1
        try:
            self._launch(state)
        except OSError:
            return False
        return True

    def alive(self, name: str) -> bool:
        """Whether the named child is running now."""
        state = self.children.get(name)
        return bool(state and state.proc and state.proc.poll() is None)

    def pid(self, name: str) -> int | None:
        """Process id of the named child's current process (None if never started)."""
        state = self.children.get(name)
        return state.proc.pid if state and state.proc else None

    # ------------------------------------------------------------------ stop
    def _signal_all(self, sig: int) -> None:
        for state in self.children.values():
            proc = state.proc
            if proc is None:
                continue
            try:
                os.killpg(proc.pid, sig)  # the child is its group's leader (setsid)
            except (ProcessLookupError, PermissionError):
                pass

    def _wait_all(self, deadline: float) -> bool:
        """Reap children until all exited or ``deadline`` (monotonic [s]); True if all exited."""
        while True:
            running = [
                s for s in self.children.values() if s.proc is not None and s.proc.poll() is None
            ]
            if not running:
                return True
            if time.monotonic() >= deadline:
                return False
            time.sleep(0.05)

    def _groups_alive(self) -> bool:
        for state in self.children.values():
            if state.proc is None:
                continue
            try:
                os.killpg(state.proc.pid, 0)
            except (ProcessLookupError, PermissionError):
                continue
            return True
        return False

    def stop(self) -> dict[str, int | None]:
        """Stop every child: SIGINT, then SIGTERM, then SIGKILL, to whole process groups.

        Returns:
            The exit code of every child by name (None if it could not be reaped).
        """
        self.stopping = True
        t0 = time.monotonic()
        self._signal_all(signal.SIGINT)
        done = self._wait_all(t0 + self.sigint_grace_s)
        if not done or self._groups_alive():
            self._signal_all(signal.SIGTERM)
            done = self._wait_all(t0 + self.sigint_grace_s + self.sigterm_grace_s)
        if not done or self._groups_alive():
            self._signal_all(signal.SIGKILL)
            self._wait_all(t0 + self.sigint_grace_s + self.sigterm_grace_s + self.kill_grace_s)
        codes = {}
        for name, state in self.children.items():
            code = state.proc.poll() if state.proc is not None else None
            if state.exit_code is None:
                state.exit_code = code
            codes[name] = code
        return codes


@dataclass
class ResourceSampler:
    """Samples CPU time and RSS of the supervised children with psutil (about every 1 s).

    Definitions:
        ``cpu_percent``: CPU seconds (user + system) of all children and their descendants over
        the sampled wall time, x100 (100 = one core busy all the time; 2 cores -> up to 200).
        ``peak_rss_mb_per_robot``: the peak, over samples, of the total RSS of the navigator,
        commander and group processes, divided by the number of robots [MB = 2**20 bytes].
        The simulator's RSS is reported apart (``sim_peak_rss_mb``).

    Args:
        supervisor: whose children to sample.
        robots: number of robots (divisor of the per-robot RSS).
        period_s: minimum time between samples [s].
    """

    supervisor: Supervisor
    robots: int
    period_s: float = 1.0
    _procs: dict[int, tuple[psutil.Process, str]] = field(default_factory=dict)
    _cpu_s: dict[int, float] = field(default_factory=dict)
    _first_t: float | None = None
    _last_t: float = 0.0
    peak_robot_rss_b: int = 0
    peak_sim_rss_b: int = 0
    peak_coord_rss_b: int = 0
    samples: int = 0

    def _tracked(self) -> list[tuple[psutil.Process, str]]:
        """The live children and their descendants (one scan of the process table)."""
        kinds = {}
        for state in self.supervisor.children.values():
            proc = state.proc
            if proc is not None and proc.poll() is None:
                kinds[proc.pid] = state.spec.kind
        if not kinds:
            return []
        children: dict[int, list[int]] = {}
        for info in psutil.process_iter(["ppid"]):
            children.setdefault(info.info["ppid"], []).append(info.pid)
        out = []
        stack = list(kinds.items())
        while stack:
            pid, kind = stack.pop()
            entry = self._procs.get(pid)
            if entry is None:
                try:
                    entry = (psutil.Process(pid), kind)
                except psutil.Error:
                    continue
                self._procs[pid] = entry
            out.append(entry)
            stack.extend((c, kind) for c in children.get(pid, ()))
        return out

    def maybe_sample(self, now: float | None = None, force: bool = False) -> bool:
        """Take a sample if ``period_s`` passed since the last one (or ``force``).

        Args:
            now: time.monotonic() [s]; None reads the clock.
            force: sample now whatever the period (the last sample before stopping).

        Returns:
            Whether a sample was taken.
        """
        now = time.monotonic() if now is None else now
        if not force and self._first_t is not None and now - self._last_t < self.period_s:
            return False
        robot_rss = sim_rss = 0
        for proc, kind in self._tracked():
            try:
                with proc.oneshot():
                    cpu = proc.cpu_times()
                    rss = proc.memory_info().rss
            except psutil.Error:
                continue
            self._cpu_s[proc.pid] = max(self._cpu_s.get(proc.pid, 0.0), cpu.user + cpu.system)
            if kind == "sim":
                sim_rss += rss
            elif kind == "record":
                pass  # the recorder is no robot's: its CPU counts, its memory not per robot
            elif kind == "coord":
                self.peak_coord_rss_b = max(self.peak_coord_rss_b, rss)
            else:
                robot_rss += rss
        self.peak_robot_rss_b = max(self.peak_robot_rss_b, robot_rss)
        self.peak_sim_rss_b = max(self.peak_sim_rss_b, sim_rss)
        if self._first_t is None:
            self._first_t = now
        self._last_t = now
        self.samples += 1
        return True

    def result(self) -> dict[str, float | None]:
        """The figures so far.

        Returns:
            ``cpu_percent`` [%], ``peak_rss_mb_per_robot`` [MB], ``sim_peak_rss_mb`` [MB]
            (None before two samples / without robots).
        """
        span = (self._last_t - self._first_t) if self._first_t is not None else 0.0
        cpu = 100.0 * sum(self._cpu_s.values()) / span if span > 0 else None
        per_robot = (
            self.peak_robot_rss_b / 2**20 / self.robots if self.robots and self.samples else None
        )
        sim = self.peak_sim_rss_b / 2**20 if self.samples else None
        return {"cpu_percent": cpu, "peak_rss_mb_per_robot": per_robot, "sim_peak_rss_mb": sim}


class StopFlag:
    """A SIGINT/SIGTERM handler that only records the first signal; the caller's loop polls it.

    Install with ``signal.signal(sig, flag)``; ``bool(flag)`` is True once a signal came.
    """

    def __init__(self):
        self.signum: int | None = None

    def __call__(self, signum, _frame):
        if self.signum is None:
            self.signum = signum

    def __bool__(self) -> bool:
        return self.signum is not None


class LogTail:
    """The complete lines a growing log file gained since the last call (a partial last line
    waits for its end).

    Args:
        path: the log file; it need not exist yet.
    """

    def __init__(self, path: Path):
        self.path = path
        self._pos = 0
        self._partial = ""

    def lines(self) -> list[str]:
        """New complete lines, without their newline; [] when the file cannot be read."""
        try:
            with open(self.path, encoding="utf-8", errors="replace") as fh:
                fh.seek(self._pos)
                chunk = fh.read()
                self._pos = fh.tell()
        except OSError:
            return []
        *done, self._partial = (self._partial + chunk).split("\n")
        return done

