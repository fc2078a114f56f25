"""The cost ledger: CPU per robot per simulated second, by process role and by stage.

``swarm-bench --ledger`` profiles every run's process tree with py-spy (a sampling profiler, a
PyPI wheel: ``pip install -e ".[ledger]"``) from "all navigators ready" to "stopping", the same
window as the bench's ``cpu_per_robot``, and splits each process's CPU time between stages:

1. the CPU time of each process in the window (psutil, :class:`swarm_bench.proc_cpu.TreeCpu`,
   per PID) gives each role's cost;
2. py-spy's samples of that process (``record --subprocesses --format raw``; a thread blocked
   in the kernel, as in the executor's wait, is not sampled) split it between the stages in
   proportion to their samples. py-spy stops a process for the moment of each sample (its
   ``--nonblocking`` mode, tried here, read an empty stack in most samples of the simulator),
   which slows the run a little and changes nothing simulated;
3. divided by robots x simulated seconds and x 1000: ms of CPU per robot per simulated second,
   the unit of docs/design/scaling.md and of the bench's table.

A sample's stage is that of its innermost frame that matches a rule of :data:`RULES` (a
package path and optionally a function), so ``Publisher.publish`` called from the navigator's
tick is *publishing*, the planner called from ``NavigatorCore.step`` *planning*, and what is
left in ``NavigatorCore.step`` itself *navigation, other*. A process with CPU time but no
sample (py-spy missed it) counts as *unsampled*. Stages (:data:`STAGES`) in the order shown.
"""

from __future__ import annotations

import contextlib
import re
import shutil
import signal
import subprocess
import sys
from collections import Counter
from collections.abc import Iterable, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path

from swarm_common.errors import InputError

STAGES = (
    ("planning", "global planning and replanning around robots seen (planner, costmap)"),
    ("dwa", "the local planner (DWA)"),
    ("holding", "the holding pattern at a taken workstation"),
    ("perception", "scan to obstacles (perception)"),
    ("navigation", "the rest of the navigator's step: traffic rules, recovery, tracking"),
    ("commanding", "commanders and the coordinator"),
    ("messages", "building and reading messages (our code around a publish or a take)"),
    ("publishing", "rclpy Publisher.publish (serialising, Fast DDS's write)"),
    ("taking", "rclpy taking messages (Fast DDS's read, deserialising)"),
    ("lockstep", "the lockstep: the tick gate, waits, stall reports"),
    ("executor", "the rclpy executor's own work (wait sets, tasks, timers)"),
    ("unattributed", "a sample without a Python frame"),
    ("physics", "the simulator's physics step and collisions (PyBullet)"),
    ("lidar", "the simulator's lidar"),
    ("metrics", "swarm-up's metrics listener and supervision"),
    ("other", "anything else sampled"),
    ("unsampled", "CPU time of a process py-spy took no sample of"),
)
"""(stage, what it holds), in the ledger's order."""
STAGE_NAMES = tuple(name for name, _ in STAGES)

RULES: tuple[tuple[str, str, str | None], ...] = (
    ("publishing", "rclpy/publisher.py", None),
    ("taking", "rclpy/executors.py", "_take_subscription"),
    ("taking", "rclpy/subscription.py", None),
    ("executor", "rclpy/", None),
    ("executor", "swarm_ros/session.py", None),
    ("executor", "swarm_sim/node.py", "spin"),
    ("executor", "swarm_up/answers.py", "spin_batched"),
    ("planning", "swarm_nav/planner", None),
    ("planning", "swarm_nav/costmap", None),
    ("dwa", "swarm_nav/dwa", None),
    ("holding", "swarm_nav/holding", None),
    ("perception", "swarm_nav/perception", None),
    ("navigation", "swarm_nav/", None),
    ("commanding", "swarm_commander/", None),
    ("commanding", "swarm_coordinator/", None),
    ("lockstep", "swarm_common/lockstep.py", None),
    ("lockstep", "swarm_common/stall.py", None),
    ("lockstep", "swarm_sim/tick.py", None),
    ("lockstep", "swarm_sim/loop.py", None),
    ("lidar", "swarm_sim/lidar", None),
    ("lidar", "swarm_sim/sensors.py", None),
    ("physics", "swarm_sim/engine.py", None),
    ("physics", "swarm_sim/kinematics.py", None),
    ("physics", "swarm_sim/separation_kernels.py", None),
    ("messages", "swarm_common/cdr.py", None),
    ("messages", "swarm_common/nav_status.py", None),
    ("messages", "swarm_ros/", None),
    ("messages", "swarm_sim/node.py", None),
    ("messages", "swarm_up/group.py", None),
    ("messages", "swarm_up/answers.py", None),
    ("metrics", "swarm_metrics/", None),
    ("metrics", "swarm_up/", None),
)
"""(stage, path fragment, function or None): the first rule whose fragment is in the frame's
file path (and whose function, if given, is the frame's, without its class: ``publish`` matches
py-spy's ``Publisher.publish``) gives the frame's stage."""

ROLES = (("sim", re.compile(r"swarm[-_]sim")), ("group", re.compile(r"swarm_up\.group")),
         ("navigator", re.compile(r"swarm[-_]nav")),
         ("commander", re.compile(r"swarm[-_]commander")),
         ("coordinator", re.compile(r"swarm[-_]coordinator")),
         ("recorder", re.compile(r"swarm_record")), ("discovery", re.compile(r"discovery")))
"""(role, pattern on the command line): a process's role is the first that matches, else
``swarm-up`` for swarm-up itself, else ``other``."""

_PROCESS = re.compile(r'^process (\d+):"(.*)"$')
_FRAME = re.compile(r"^(.*) \((.*):(\d+)\)$")


def role_of(cmdline: str) -> str:
    """A process's role from its command line (:data:`ROLES`)."""
    for name, pattern in ROLES:
        if pattern.search(cmdline):
            return name
    return "swarm-up" if "swarm-up" in cmdline or "swarm_up" in cmdline else "other"


@dataclass(frozen=True)
class Sample:
    """One line of py-spy's raw output: a stack and how often it was seen.

    Attributes:
        pid: the innermost process of the stack.
        cmdline: that process's command line.
        frames: ``(function, file)`` of each Python frame, outermost first.
        count: samples.
    """

    pid: int
    cmdline: str
    frames: tuple[tuple[str, str], ...]
    count: int


def parse_raw(text: str) -> Iterator[Sample]:
    """The samples of py-spy's ``--format raw`` output (``--subprocesses``: the stack starts
    with ``process PID:"cmdline"`` frames, the parent's first). Lines that do not parse, and
    stacks of no process, are skipped."""
    for line in text.splitlines():
        stack, _, count = line.rpartition(" ")
        if not stack or not count.isdigit():
            continue
        pid, cmdline, frames = None, "", []
        for part in stack.split(";"):
            m = _PROCESS.match(part)
            if m:
                pid, cmdline, frames = int(m.group(1)), m.group(2), []
                continue
            f = _FRAME.match(part)
            if f:
                frames.append((f.group(1), f.group(2)))
        if pid is not None:
            yield Sample(pid, cmdline, tuple(frames), int(count))


def stage_of(frames: Iterable[tuple[str, str]]) -> str:
    """The stage of a stack: its innermost frame's that matches a rule (:data:`RULES`), else
    ``other``; ``unattributed`` for a stack without a Python frame."""
    frames = tuple(frames)
    if not frames:
        return "unattributed"
    for function, path in reversed(frames):
        path = path.replace("\\", "/")
        function = function.rsplit(".", 1)[-1]
        for stage, fragment, name in RULES:
            if fragment in path and (name is None or name == function):
                return stage
    return "other"


def build_ledger(samples: Iterable[Sample], cpu_s: Mapping[int, float],
                 roles: Mapping[int, str], robots: int, sim_s: float) -> dict:
    """The ledger of one run.

    Args:
        samples: py-spy's samples over the window (:func:`parse_raw`).
        cpu_s: [s] CPU time of each PID over the window.
        roles: each PID's role (:func:`role_of`); a PID without one takes its samples' command
            line's.
        robots: the run's robots (> 0).
        sim_s: [s] simulated seconds in the window (> 0).

    Returns:
        ``{"unit", "robots", "sim_s", "samples", "total", "stages": {stage: ms},
        "roles": {role: {"total": ms, "stages": {stage: ms}}}}``, every figure in ms of CPU per
        robot per simulated second; only stages and roles that cost something are listed.

    Raises:
        ValueError: ``robots`` or ``sim_s`` not positive.
    """
    if robots <= 0 or not sim_s > 0:
        raise ValueError(f"robots ({robots}) and sim_s ({sim_s}) must be positive")
    per_pid: dict[int, Counter] = {}
    roles = dict(roles)
    total_samples = 0
    for s in samples:
        per_pid.setdefault(s.pid, Counter())[stage_of(s.frames)] += s.count
        roles.setdefault(s.pid, role_of(s.cmdline))
        total_samples += s.count
    scale = 1000.0 / (robots * sim_s)
    by_role: dict[str, Counter] = {}
    for pid, used in cpu_s.items():
        if used <= 0:
            continue
        counts = per_pid.get(pid) or Counter(unsampled=1)
        taken = sum(counts.values())
        acc = by_role.setdefault(roles.get(pid, "other"), Counter())
        for stage, count in counts.items():
            acc[stage] += used * count / taken * scale
    stages: Counter = Counter()
    for acc in by_role.values():
        stages.update(acc)

    def ordered(counter: Mapping[str, float]) -> dict[str, float]:
        return {k: counter[k] for k in STAGE_NAMES if counter.get(k, 0.0) > 0}

    return {
        "unit": "ms of CPU per robot per simulated second",
        "robots": robots,
        "sim_s": sim_s,
        "samples": total_samples,
        "total": sum(stages.values()),
        "stages": ordered(stages),
        "roles": {role: {"total": sum(acc.values()), "stages": ordered(acc)}
                  for role, acc in sorted(by_role.items(), key=lambda kv: -sum(kv[1].values()))},
    }


def mean_ledger(ledgers: list[dict]) -> dict | None:
    """The mean of several runs' ledgers of one size (None for none): every figure averaged
    over the runs, a stage or role missing from a run counting 0 there."""
    if not ledgers:
        return None
    n = len(ledgers)
    stages: Counter = Counter()
    roles: Counter = Counter()
    role_stages: dict[str, Counter] = {}
    for led in ledgers:
        stages.update(led["stages"])
        for role, part in led["roles"].items():
            roles[role] += part["total"]
            role_stages.setdefault(role, Counter()).update(part["stages"])

    def ordered(counter: Counter) -> dict[str, float]:
        return {k: counter[k] / n for k in STAGE_NAMES if k in counter}

    return {"unit": ledgers[0]["unit"], "robots": ledgers[0]["robots"], "runs": n,
            "sim_s": sum(led["sim_s"] for led in ledgers) / n,
            "samples": sum(led["samples"] for led in ledgers),
            "total": sum(led["total"] for led in ledgers) / n,
            "stages": ordered(stages),
            "roles": {role: {"total": total / n, "stages": ordered(role_stages[role])}
                      for role, total in roles.most_common()}}


# ------------------------------------------------------------------------------------ profiling
SAMPLE_RATE_HZ = 100
"""py-spy's samples per second and process (its default)."""
STOP_TIMEOUT_S = 60.0
"""[s] wall py-spy gets to write its file after SIGINT."""


def py_spy_path() -> str:
    """The ``py-spy`` executable: beside this Python, else on ``PATH``.

    Raises:
        InputError: not installed (names ``--ledger``).
    """
    here = Path(sys.executable).parent / "py-spy"
    if here.is_file():
        return str(here)
    found = shutil.which("py-spy")
    if found is None:
        raise InputError('--ledger: py-spy is not installed (pip install -e ".[ledger]", or '
                         "pip install py-spy)")
    return found


class Profiler:
    """py-spy recording one process tree to a raw file, from :meth:`start` to :meth:`stop`.

    Args:
        executable: ``py-spy`` (:func:`py_spy_path`).
        output: the raw file to write.
        rate: samples per second and process.
    """

    def __init__(self, executable: str, output: Path, rate: int = SAMPLE_RATE_HZ):
        self.executable, self.output, self.rate = executable, Path(output), int(rate)
        self._proc: subprocess.Popen | None = None
        self._samples: list[Sample] | None = None
        self.log = self.output.with_suffix(".log")

    def start(self, pid: int) -> None:
        """Attach to ``pid`` and every process it starts (idempotent)."""
        if self._proc is not None:
            return
        argv = [self.executable, "record", "--pid", str(pid), "--subprocesses",
                "--full-filenames", "--format", "raw",
                "--rate", str(self.rate), "--output", str(self.output)]
        with open(self.log, "wb") as log:
            self._proc = subprocess.Popen(argv, stdout=log, stderr=subprocess.STDOUT,
                                          stdin=subprocess.DEVNULL)

    def stop(self) -> list[Sample]:
        """Stop recording (SIGINT: py-spy writes its file) and return the samples ([] when it
        wrote none; its log says why). Idempotent."""
        if self._proc is None:
            return []
        if self._samples is not None:
            return self._samples
        if self._proc.poll() is None:
            self._proc.send_signal(signal.SIGINT)
        try:
            self._proc.wait(STOP_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            self._proc.kill()
            self._proc.wait()
        self._samples = []
        with contextlib.suppress(OSError):
            self._samples = list(parse_raw(self.output.read_text(errors="replace")))
        return self._samples


# -------------------------------------------------------------------------------------- display
ROLE_ORDER = ("group", "navigator", "commander", "sim", "coordinator", "swarm-up", "recorder",
              "discovery", "other")
"""Roles in the order the table and the chart show them."""


def print_ledger(summary: list[dict], title: str) -> None:
    """The ledger table of every size: a row per stage, a column per size (all roles), then the
    same per role (rich; plain text off a terminal)."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    rows = [s for s in summary if s.get("ledger")]
    if not rows:
        return
    table = Table(title=title, box=box.SIMPLE_HEAD, pad_edge=False)
    table.add_column("stage [ms CPU / robot / sim s]")
    for s in rows:
        table.add_column(f"{s['size']} robots", justify="right")
    used = [k for k in STAGE_NAMES if any(k in s["ledger"]["stages"] for s in rows)]
    for stage in used:
        table.add_row(stage, *(f"{s['ledger']['stages'].get(stage, 0.0):.2f}" for s in rows))
    table.add_row("total", *(f"{s['ledger']['total']:.2f}" for s in rows), style="bold")
    roles = [r for r in ROLE_ORDER if any(r in s["ledger"]["roles"] for s in rows)]
    for role in roles:
        table.add_row(f"  of it {role}", *(
            f"{s['ledger']['roles'].get(role, {'total': 0.0})['total']:.2f}" for s in rows))
    Console(width=None if sys.stdout.isatty() else 160).print(table)


def write_ledger_plot(path: Path, summary: list[dict], title: str) -> None:
    """A stacked bar per size and role (the simulator, the robots' processes, the rest), split
    by stage (PNG, matplotlib's Agg)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = [s for s in sorted(summary, key=lambda s: s["size"]) if s.get("ledger")]
    if not rows:
        return
    fig, axes = plt.subplots(1, len(rows), figsize=(4.5 * len(rows) + 3, 5),
                             constrained_layout=True, squeeze=False)
    cmap = plt.get_cmap("tab20")
    colours = {k: cmap(i % 20) for i, k in enumerate(STAGE_NAMES)}
    top = max(max(r["total"] for r in s["ledger"]["roles"].values()) for s in rows)
    for ax, s in zip(axes[0], rows, strict=True):
        roles = [r for r in ROLE_ORDER if r in s["ledger"]["roles"]]
        for i, role in enumerate(roles):
            bottom = 0.0
            for stage in STAGE_NAMES:
                v = s["ledger"]["roles"][role]["stages"].get(stage, 0.0)
                if v > 0:
                    ax.bar(i, v, bottom=bottom, color=colours[stage], edgecolor="white",
                           linewidth=0.5, label=stage)
                    bottom += v
        ax.set_xticks(range(len(roles)), roles, rotation=30)
        ax.set_ylim(0, top * 1.08)
        ax.set_title(f"{s['size']} robots: {s['ledger']['total']:.1f} ms in all")
        ax.set_ylabel("ms of CPU per robot per simulated second")
        ax.grid(True, axis="y", alpha=0.3)
    handles, labels = [], []
    for ax in axes[0]:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    order = sorted(range(len(labels)), key=lambda i: STAGE_NAMES.index(labels[i]))
    fig.legend([handles[i] for i in order], [labels[i] for i in order], loc="outside right")
    fig.suptitle(title)
    fig.savefig(path, format="png", dpi=100)
    plt.close(fig)
