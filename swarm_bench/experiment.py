"""``swarm-experiment``: decentralized against centralized coordination, by the protocol.

::

    swarm-experiment [--sizes 5,10,20,40] [--duration 300] [--runs 3] [--seed 0]
                     [--world slim_blockage] [--modes decentralized,centralized]
                     [--fault-spec SPEC ... | --no-faults] [--fault-size N] [--warmup 120]
                     [--output DIR] [--processes per-robot|K] [--swarm-up PATH]

For every mode M, size N and run r (seed S + r, the same seeds in both modes) it runs, with
``swarm-bench``'s machinery (:func:`swarm_bench.bench.run_swarm_up`: progress, CPU of the process
tree, the metrics file)::

    swarm-up --swarm-size N --world W --seed S+r --commanders --rtf 0 --duration D
             --coordination M [--faults SPEC]

and, for every ``--fault-spec SPEC`` (default :data:`DEFAULT_FAULTS`: robot 3 dies at 180 s;
the coordinator dies at 180 s and is restarted 30 s later), the same at ``--fault-size`` with
``--faults SPEC`` passed through to ``swarm-up`` as given, plus the no-fault runs at that size
to compare with. A spec that kills the coordinator runs only in the modes that have one
(centralized). It then writes the report directory (``--output``):

- ``report.md``: the exact commands, git commit, machine, settings, what "reproducible" means
  and how many runs were, one table per measure (mean and 95 % interval across the seeds,
  Student's t), throughput against swarm size, the fault curves and their dips, a Little's-law
  check and the threats to validity (shared/reference/experiment_protocol.md);
- ``*.png``: the figures (matplotlib, Agg), embedded in the report;
- ``experiment.json``: every run's record (swarm-up's command, exit code, CPU, and its whole
  ``--metrics`` JSON) and the cell summaries; written again after every run, so an interrupted
  experiment keeps what it finished.

Measures (per run; ``swarm_metrics.aggregate`` defines the underlying figures): throughput
after the warm-up [tasks per simulated hour] (tasks completed after ``--warmup`` s over the time
after it), time to task mean and 95th percentile [s], holding per robot [s] (the navigator's
holding pattern plus, centralized, the time at the coordinator's waiting spots), collisions
(robot-robot + robot-wall), late ticks, CPU per robot [ms per simulated s], communication load
[messages and bytes per simulated second, total and per robot; the coordinator's share apart
from the map's], RTF. Fault curves: tasks completed per 30 s window of simulated time.

Exit codes: 0 every run ended well, 1 a run failed (the experiment goes on), 2 bad flags,
130 interrupted (the finished runs are kept and reported).
"""

from __future__ import annotations

import argparse
import math
import sys
from dataclasses import dataclass
from pathlib import Path

from swarm_common import cli
from swarm_common.errors import EXIT_OK, InputError
from swarm_common.faults import KILL_COORDINATOR
from swarm_up.args import default_run_dir

PROG = "swarm-experiment"
MODES = ("decentralized", "centralized")
WINDOW_S = 30.0  # [s] simulated: fault-curve window
DEFAULT_FAULTS = ("kill-robot:3@180", "kill-coordinator@180+30")
"""The protocol's fault kinds that decide the comparison (experiment_protocol.md, "Faults"): a
whole robot dead, and the coordinator dead then restarted by its supervisor; both after the
default 120 s warm-up, leaving 120 s of a 300 s run to see the recovery."""
SCHEMA_VERSION = 1


# ---------------------------------------------------------------------------------------- flags
def _modes(text: str) -> tuple[str, ...]:
    parts = tuple(p.strip() for p in text.split(","))
    bad = [p for p in parts if p not in MODES]
    if bad or not text.strip():
        raise argparse.ArgumentTypeError(
            f"must be a comma-separated list of {', '.join(MODES)}, got {text!r}")
    return tuple(dict.fromkeys(parts))


def _fault_spec(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    return text.strip()


def build_parser() -> argparse.ArgumentParser:
    """The ``swarm-experiment`` argument parser."""
    from swarm_bench.bench import sweep_parser

    p = sweep_parser(
        PROG, "Compare decentralized with centralized coordination on the same world, seeds "
        "and sizes (and faults): runs swarm-up for every cell and writes a report directory "
        "(Markdown, PNG plots, raw JSON).", "experiment", "runs", (5, 10, 20, 40), 3,
        "runs per cell; run r uses seed S+r in every mode")
    p.add_argument("--modes", type=_modes, default=MODES, metavar="M,M",
                   help="coordination modes (default: decentralized,centralized)")
    p.add_argument("--fault-spec", type=_fault_spec, action="append", default=None,
                   metavar="SPEC", help="a fault scenario, passed to swarm-up as --faults SPEC "
                   "(repeatable; each is one more cell per mode at --fault-size; a spec that "
                   "kills the coordinator runs only in centralized mode; default: "
                   f"{' and '.join(DEFAULT_FAULTS)})")
    p.add_argument("--no-faults", action="store_true",
                   help="run no fault cells (only the sizes)")
    p.add_argument("--fault-size", type=cli.positive_int, default=None, metavar="N",
                   help="swarm size of the fault runs (default: 10 if in --sizes, else the "
                   "largest size)")
    p.add_argument("--fault-time", type=cli.non_negative_float, default=None, metavar="SEC",
                   help="simulated time the faults start, marked on the fault curves "
                   "(default: each spec's earliest fault)")
    p.add_argument("--warmup", type=cli.non_negative_float, default=120.0, metavar="SEC",
                   help="simulated seconds left out of the throughput (default: %(default)g)")
    p.add_argument("--output", type=Path, default=None, metavar="DIR",
                   help="report directory (default: experiment-<timestamp>/)")
    p.add_argument("--swarm-up", type=Path, default=None, metavar="PATH",
                   help="the swarm-up executable (default: the one beside this Python)")
    return p


@dataclass(frozen=True)
class Cell:
    """One (mode, size, fault) cell: ``runs`` runs of swarm-up.

    Attributes:
        mode: coordination mode.
        size: robots.
        fault: the ``--faults`` spec, or ``""`` for none.
        label: the run directory stem (``centralized-n10`` / ``centralized-n10-f1``).
    """

    mode: str
    size: int
    fault: str
    label: str


@dataclass(frozen=True)
class ExperimentConfig:
    """The validated flags (see :func:`build_parser`); ``output`` absolute."""

    sizes: tuple[int, ...]
    duration_s: float
    runs: int
    seed: int
    world: str
    modes: tuple[str, ...]
    faults: tuple[str, ...]
    fault_size: int | None
    fault_times: tuple[float, ...]  # [s] simulated, one per spec of ``faults``
    fault_modes: tuple[tuple[str, ...], ...]  # the modes each spec runs in
    warmup_s: float
    output: Path
    processes: str | int | None
    swarm_up: Path

    def cells(self) -> list[Cell]:
        """Every cell, in run order: sizes ascending with both modes per size, then faults."""
        out = [Cell(m, n, "", f"{m}-n{n}") for n in self.sizes for m in self.modes]
        if self.faults and self.fault_size not in self.sizes:  # the fault runs' baseline
            out += [Cell(m, self.fault_size, "", f"{m}-n{self.fault_size}") for m in self.modes]
        for k, (spec, modes) in enumerate(zip(self.faults, self.fault_modes, strict=True),
                                          start=1):
            out += [Cell(m, self.fault_size, spec, f"{m}-n{self.fault_size}-f{k}")
                    for m in modes]
        return out


def validate(args: argparse.Namespace) -> ExperimentConfig:
    """Check what argparse cannot.

    Raises:
        InputError: the first bad flag (one line naming it).
    """
    from swarm_bench.bench import swarm_up_path
    from swarm_common.world import resolve_world

    try:
        resolve_world(args.world)
    except InputError as exc:
        msg = str(exc)
        raise InputError(msg if msg.startswith("--world") else f"--world: {msg}") from None
    world = str(Path(args.world).resolve()) if Path(args.world).is_file() else args.world
    if args.warmup >= args.duration:
        raise InputError(f"--warmup: {args.warmup:g} s leaves nothing of --duration "
                         f"{args.duration:g} s")
    out = args.output if args.output is not None else default_run_dir(Path("."), "experiment-")
    if out.exists() and not out.is_dir():
        raise InputError(f"--output: '{out}' exists and is not a directory")
    if not out.expanduser().resolve().parent.is_dir():
        raise InputError(f"--output: directory '{out.expanduser().resolve().parent}' "
                         "does not exist")
    if args.no_faults and args.fault_spec:
        raise InputError("--no-faults: not together with --fault-spec")
    specs = () if args.no_faults else tuple(args.fault_spec or DEFAULT_FAULTS)
    fault_size = args.fault_size
    if specs and fault_size is None:
        fault_size = 10 if 10 in args.sizes else max(args.sizes)
    times, modes = [], []
    for spec in specs:
        faults = _parse_spec(spec, fault_size, args.duration)
        times.append(args.fault_time if args.fault_time is not None
                     else min(f.at for f in faults))
        central = any(f.kind == KILL_COORDINATOR for f in faults)
        modes.append(tuple(m for m in args.modes if m == "centralized" or not central))
        if not modes[-1]:
            raise InputError(f"--fault-spec: '{spec}' kills the coordinator, which only "
                             "--modes centralized has")
    return ExperimentConfig(
        sizes=args.sizes, duration_s=args.duration, runs=args.runs, seed=args.seed,
        world=world, modes=args.modes, faults=specs, fault_size=fault_size,
        fault_times=tuple(times), fault_modes=tuple(modes), warmup_s=args.warmup,
        output=out.expanduser().resolve(), processes=args.processes,
        swarm_up=swarm_up_path(args.swarm_up))


def _parse_spec(spec: str, size: int, duration: float):
    """The faults of one ``--fault-spec`` for a swarm of ``size`` (swarm-up's own parser).

    Raises:
        InputError: the spec is malformed or does not fit the run (names ``--fault-spec``).
    """
    from swarm_common.faults import parse_faults

    robots = tuple(f"Srobot{i}" for i in range(1, size + 1))  # swarm-up's default prefix
    try:
        return parse_faults(spec, robots, duration=duration)
    except InputError as exc:
        raise InputError(f"--fault-spec: {exc}") from None


# ------------------------------------------------------------------------------------ figures
def t_interval(values: list[float], level: float = 0.95) -> tuple[float | None, float | None]:
    """Mean and the half-width of its Student's-t interval.

    Args:
        values: one figure per run (seed).
        level: the interval's confidence.

    Returns:
        ``(mean, half_width)``: ``(None, None)`` without values, half-width None for one value.
    """
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    if not vals:
        return None, None
    n = len(vals)
    mean = sum(vals) / n
    if n < 2:
        return mean, None
    from scipy.stats import t as student

    sd = math.sqrt(sum((v - mean) ** 2 for v in vals) / (n - 1))
    return mean, float(student.ppf(0.5 + level / 2, n - 1)) * sd / math.sqrt(n)


def run_figures(record: dict, warmup_s: float) -> dict | None:
    """The protocol's figures of one swarm-up run (None if it did not end well).

    Args:
        record: a :func:`swarm_bench.bench.run_swarm_up` record.
        warmup_s: [s] simulated time left out of the throughput.

    Returns:
        ``throughput`` [tasks/h after the warm-up], ``ttt_mean``/``ttt_p95`` [s],
        ``holding_per_robot`` [s], ``idle_robots`` (robots that completed no task) and
        ``min_tasks`` (the fewest tasks of a robot), ``collisions``, ``late_ticks``,
        ``cpu_per_robot_ms``
        [ms per simulated s], ``comm_msgs``/``comm_bytes`` [per simulated s, total],
        ``coord_msgs``/``coord_bytes`` (without the map), ``comm_bytes_per_robot``, ``rtf``,
        ``tasks``, ``reproducible``, ``reservation_conflicts``, ``task_times``.
    """
    m = record.get("metrics")
    if record.get("exit_code") != EXIT_OK or not isinstance(m, dict):
        return None
    n = m.get("robots") or 1
    sim = m.get("sim_time_s") or 0.0
    times = [float(t) for t in m.get("task_times_s") or []]
    after = [t for t in times if t > warmup_s]
    thr = len(after) / ((sim - warmup_s) / 3600.0) if sim > warmup_s else None
    col = m.get("collisions") or {}
    comm = m.get("comm") or {}
    by_topic = comm.get("by_topic") or {}
    coord = [v for k, v in by_topic.items() if k != "map"]
    holding = (m.get("holding_time_s") or 0.0) + (m.get("coordinator_wait_s") or 0.0)
    cpu = record.get("cpu_per_robot")
    spread = m.get("tasks_per_robot") or {}
    return {
        "throughput": thr,
        "ttt_mean": m.get("time_to_task_mean_s"),
        "ttt_p95": m.get("time_to_task_p95_s"),
        "holding_per_robot": holding / n,
        "idle_robots": spread.get("without_task"),
        "min_tasks": spread.get("min"),
        "collisions": (col.get("robot_robot") or 0) + (col.get("robot_wall") or 0),
        "late_ticks": m.get("late_ticks"),
        "cpu_per_robot_ms": cpu * 1000.0 if cpu is not None else None,
        "comm_msgs": comm.get("messages_per_s"),
        "comm_bytes": comm.get("bytes_per_s"),
        "coord_msgs": sum(v["messages"] for v in coord) / sim if sim else None,
        "coord_bytes": sum(v["bytes"] for v in coord) / sim if sim else None,
        "comm_bytes_per_robot": (comm.get("bytes_per_s") or 0.0) / n,
        "rtf": m.get("rtf"),
        "tasks": m.get("tasks_completed"),
        "reproducible": m.get("reproducible"),
        "reservation_conflicts": m.get("reservation_conflicts"),
        "task_times": times,
        "sim_time": sim,
        "robots": n,
    }


MEASURES = (
    ("throughput", "throughput after warm-up [tasks/h]", 1),
    ("ttt_mean", "time to task, mean [s]", 1),
    ("ttt_p95", "time to task, 95th percentile [s]", 1),
    ("holding_per_robot", "holding + waiting per robot [s]", 1),
    ("idle_robots", "robots without a task", 1),
    ("min_tasks", "tasks of the robot with the fewest", 1),
    ("collisions", "collisions (robot-robot + wall)", 1),
    ("late_ticks", "late ticks", 1),
    ("cpu_per_robot_ms", "CPU per robot [ms per sim s]", 1),
    ("comm_msgs", "communication, total [msg per sim s]", 2),
    ("comm_bytes", "communication, total [bytes per sim s]", 0),
    ("coord_msgs", "coordinator traffic [msg per sim s]", 2),
    ("coord_bytes", "coordinator traffic [bytes per sim s]", 0),
    ("comm_bytes_per_robot", "communication per robot [bytes per sim s]", 0),
    ("rtf", "real-time factor", 2),
)


def summarize_cell(cell: Cell, records: list[dict], warmup_s: float) -> dict:
    """Mean and 95 % half-width of every measure over a cell's runs."""
    figs = [f for f in (run_figures(r, warmup_s) for r in records) if f is not None]
    out = {"mode": cell.mode, "size": cell.size, "fault": cell.fault, "label": cell.label,
           "runs": len(records), "runs_ok": len(figs),
           "reproducible_runs": sum(1 for f in figs if f["reproducible"]),
           "reservation_conflicts": sum(f["reservation_conflicts"] or 0 for f in figs)}
    for key, _, _ in MEASURES:
        mean, half = t_interval([f[key] for f in figs if f[key] is not None])
        out[key] = {"mean": mean, "ci95": half}
    return out


def window_counts(times: list[float], duration_s: float,
                  window_s: float = WINDOW_S) -> list[int]:
    """Tasks completed in each window of simulated time [0, w), [w, 2w), ... up to the end."""
    k = max(1, int(math.ceil(duration_s / window_s)))
    counts = [0] * k
    for t in times:
        i = min(k - 1, int(t // window_s))
        counts[i] += 1
    return counts


def fault_effect(base: list[float], faulted: list[float], fault_s: float, duration_s: float,
                 window_s: float = WINDOW_S) -> dict:
    """The dip and recovery of one fault run against the no-fault run with the same seed.

    Args:
        base, faulted: task completion times [s] of the two runs.
        fault_s: [s] when the fault started.
        duration_s: [s] the runs' length.

    Returns:
        ``tasks_lost``: tasks the no-fault run completed after ``fault_s`` minus the faulted
        run's; ``recovery_s``: from ``fault_s`` to the start of the first window after it from
        which every window's count is within 10 % of the no-fault run's mean rate after
        ``fault_s`` (None if never).
    """
    lost = sum(1 for t in base if t >= fault_s) - sum(1 for t in faulted if t >= fault_s)
    b, f = window_counts(base, duration_s, window_s), window_counts(faulted, duration_s, window_s)
    first = int(fault_s // window_s)
    ref = b[first:]
    rate = sum(ref) / len(ref) if ref else 0.0
    recovery = None
    for i in range(first, len(f)):
        if all(c >= 0.9 * rate for c in f[i:]):
            recovery = max(0.0, i * window_s - fault_s)
            break
    return {"tasks_lost": lost, "recovery_s": recovery}


# ----------------------------------------------------------------------------------- plotting
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_measure(path: Path, summaries: list[dict], key: str, label: str, title: str) -> None:
    """One measure against swarm size: mean with its 95 % band, one line per mode."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
    for mode in MODES:
        rows = sorted((s for s in summaries if s["mode"] == mode and not s["fault"]
                       and s[key]["mean"] is not None), key=lambda s: s["size"])
        if not rows:
            continue
        xs = [s["size"] for s in rows]
        ys = [s[key]["mean"] for s in rows]
        hw = [s[key]["ci95"] or 0.0 for s in rows]
        line, = ax.plot(xs, ys, marker="o", label=mode)
        ax.fill_between(xs, [y - h for y, h in zip(ys, hw, strict=True)],
                        [y + h for y, h in zip(ys, hw, strict=True)],
                        color=line.get_color(), alpha=0.2)
    ax.set_xticks(sorted({s["size"] for s in summaries if not s["fault"]}))
    ax.set_xlabel("swarm size [robots]")
    ax.set_ylabel(label)
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend()
    fig.savefig(path, format="png", dpi=100)
    plt.close(fig)


def plot_fault(path: Path, curves: dict[str, list[float]], fault_s: float | None,
               title: str) -> None:
    """Tasks per 30 s window over simulated time (mean over seeds), one line per mode/case."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2), constrained_layout=True)
    for name, counts in curves.items():
        xs = [(i + 0.5) * WINDOW_S for i in range(len(counts))]
        ax.plot(xs, counts, marker=".", label=name,
                linestyle="--" if "no fault" in name else "-")
    if fault_s is not None:
        ax.axvline(fault_s, color="red", linewidth=1.0, label=f"fault at {fault_s:g} s")
    ax.set_xlabel("simulated time [s]")
    ax.set_ylabel(f"tasks completed per {WINDOW_S:g} s")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    fig.savefig(path, format="png", dpi=100)
    plt.close(fig)


# ------------------------------------------------------------------------------------- report
def _fmt(stat: dict, digits: int) -> str:
    mean, half = stat.get("mean"), stat.get("ci95")
    if mean is None:
        return "-"
    text = f"{mean:.{digits}f}"
    return text if half is None else f"{text} ± {half:.{digits}f}"


def _cmd(argv) -> str:
    import shlex

    return " ".join(shlex.quote(str(a)) for a in argv)


def write_report(cfg: ExperimentConfig, doc: dict) -> Path:
    """Write ``report.md`` and the PNGs from ``doc`` (the experiment JSON).

    Returns:
        The report's path.
    """
    out = cfg.output
    summaries = doc["summary"]
    plain = [s for s in summaries if not s["fault"]]
    lines = [f"# Decentralized vs centralized coordination: {Path(cfg.world).stem}", ""]
    lines += ["## How this was made", "", "```bash", _cmd(doc["command"]), "```", "",
              f"- git commit: `{doc['git'].get('commit')}`"
              f"{' (with uncommitted changes)' if doc['git'].get('dirty') else ''}",
              f"- machine: {doc['machine'].get('cores')} cores, Python "
              f"{doc['machine'].get('python')}, rclpy {doc['machine'].get('rclpy')}, "
              f"{doc['machine'].get('rmw')}, {doc['machine'].get('platform')}; load average "
              f"{doc['machine'].get('load_average_start')} at the start, "
              f"{doc['machine'].get('load_average_end')} at the end",
              f"- started {doc['started']}, finished {doc['finished']}",
              f"- every cell: {cfg.runs} run(s), seeds {cfg.seed}..{cfg.seed + cfg.runs - 1} "
              f"(the same in both modes), {cfg.duration_s:g} simulated s, `--rtf 0`, "
              f"commanders; throughput counts tasks after a warm-up of {cfg.warmup_s:g} s",
              "- each swarm-up command is in `experiment.json` (`records[i].command`); "
              "a run is e.g.:", "", "```bash",
              _cmd(doc["records"][0]["command"]) if doc["records"] else "(no run finished)",
              "```", ""]
    total = sum(s["runs_ok"] for s in summaries)
    repro = sum(s["reproducible_runs"] for s in summaries)
    conflicts = sum(s["reservation_conflicts"] for s in summaries if s["mode"] == "centralized")
    lines += ["**Reproducibility.** A run is reproducible when its simulated figures depend on "
              "the seed alone: no late tick, no goal-wait timeout, no late goal, no restart "
              f"(swarm-up's `reproducible`). {repro} of {total} runs were. Rerunning a "
              "reproducible run's command gives the same tasks, times and distances; CPU, RTF "
              "and wall times vary with the machine's load.", "",
              f"**Reservations.** {conflicts} reservation conflicts in the centralized runs "
              "(a resource reserved while another robot held it; from the coordinator's "
              "events).", ""]
    lines += ["## Results", "",
              "Mean ± half-width of the 95 % interval across seeds (Student's t; no interval "
              "with one run). A difference is claimed only where the intervals do not "
              "overlap.", ""]
    head = "| measure | " + " | ".join(f"{s['mode'][:5]}. {s['size']}" for s in plain) + " |"
    lines += [head, "|---|" + "---|" * len(plain)]
    for key, label, digits in MEASURES:
        lines.append(f"| {label} | " + " | ".join(_fmt(s[key], digits) for s in plain) + " |")
    lines.append("")
    for key, label, _ in MEASURES:
        if key in ("late_ticks",):
            continue
        png = f"{key}.png"
        plot_measure(out / png, summaries, key, label, f"{label} against swarm size")
        lines += [f"![{label}]({png})", ""]
    lines += _verdicts(plain)
    lines += _littles_law(doc, cfg)
    if cfg.faults:
        lines += _fault_section(cfg, doc)
    lines += ["## Threats to validity", "",
              "One machine with 2 cores shared with other work (CPU and RTF figures vary with "
              "its load); simulated perfect odometry; one world; the coordinator's policy "
              "(first come, first served, one waiting spot per robot, parking on the spawn "
              "grid) is one of many; the communication load counts serialized message bytes, "
              "not DDS headers, discovery or acknowledgements; the map is sent once per "
              f"navigator, so its share per second shrinks with the run's length; {cfg.runs} "
              "seed(s) per cell.", ""]
    path = out / "report.md"
    path.write_text("\n".join(lines) + "\n")
    return path


def _verdicts(plain: list[dict]) -> list[str]:
    lines = ["## Which mode wins", ""]
    for n in sorted({s["size"] for s in plain}):
        d = next((s for s in plain if s["size"] == n and s["mode"] == "decentralized"), None)
        c = next((s for s in plain if s["size"] == n and s["mode"] == "centralized"), None)
        if d is None or c is None:
            continue
        parts = []
        for key, label, digits, higher in (("throughput", "throughput", 0, True),
                                           ("ttt_mean", "mean time to task", 1, False),
                                           ("comm_bytes", "communication", 0, False)):
            a, b = d[key], c[key]
            if a["mean"] is None or b["mean"] is None:
                continue
            better = "decentralized" if (a["mean"] > b["mean"]) == higher else "centralized"
            rel = (100.0 * (b["mean"] - a["mean"]) / a["mean"]) if a["mean"] else float("nan")
            if a["ci95"] is None or b["ci95"] is None:
                verdict = f"{better} better in this one run (no interval: no claim)"
            elif abs(a["mean"] - b["mean"]) <= a["ci95"] + b["ci95"]:
                verdict = "no claimed difference (intervals overlap)"
            else:
                verdict = f"{better} better (intervals do not overlap)"
            parts.append(f"{label} {a['mean']:.{digits}f} vs {b['mean']:.{digits}f} "
                         f"(centralized {rel:+.0f} %): {verdict}")
        lines.append(f"- **{n} robots** (decentralized vs centralized): " + "; ".join(parts))
    for mode in MODES:
        rows = sorted((s for s in plain if s["mode"] == mode
                       and s["throughput"]["mean"] is not None), key=lambda s: s["size"])
        drops = [f"{a['size']}→{b['size']}" for a, b in zip(rows, rows[1:], strict=False)
                 if b["throughput"]["mean"] < a["throughput"]["mean"]]
        if rows:
            best = max(rows, key=lambda s: s["throughput"]["mean"])
            lines.append(f"- {mode}: highest throughput at {best['size']} robots "
                         f"({best['throughput']['mean']:.0f} tasks/h); throughput falls when "
                         f"robots are added: {', '.join(drops) if drops else 'never'}.")
    return lines + [""]


def _littles_law(doc: dict, cfg: ExperimentConfig) -> list[str]:
    lines = ["## Sanity check: Little's law", "",
             "Every robot always has a task, so the robots busy (N) should match throughput × "
             "mean time to task (over the whole run, warm-up included). Only tasks completed "
             "within the run count, and the tasks still open at its end are the longest ones "
             "(censored), so λ·W falls below N by more the longer the tasks are against the "
             "run; a dead robot's task never ends.", "",
             "| cell | N | λ·W (mean over runs) |", "|---|---|---|"]
    for s in doc["summary"]:
        recs = [r for r in doc["records"] if r.get("cell") == s["label"]]
        vals = []
        for r in recs:
            f = run_figures(r, 0.0)
            if f and f["ttt_mean"] and f["sim_time"]:
                vals.append(f["tasks"] / f["sim_time"] * f["ttt_mean"])
        if vals:
            lines.append(f"| {s['label']} | {s['size']} | {sum(vals) / len(vals):.1f} |")
    return lines + [""]


def _fault_section(cfg: ExperimentConfig, doc: dict) -> list[str]:
    lines = ["## Faults", "",
             "Tasks lost: tasks the no-fault run of the same seed completed after the fault "
             "time minus the faulted run's. Back within 10 %: from the fault to the first "
             f"{WINDOW_S:g} s window from which every window completes at least 90 % of the "
             "no-fault run's mean rate after the fault (\"never\": some window to the end of the "
             "run falls short; with a few tasks per window one slow window is enough).", ""]
    for k, (spec, fault_s, modes) in enumerate(
            zip(cfg.faults, cfg.fault_times, cfg.fault_modes, strict=True), start=1):
        lines += [f"### `--faults {spec}` at {cfg.fault_size} robots", ""]
        skipped = [m for m in cfg.modes if m not in modes]
        if skipped:
            lines += [f"- {', '.join(skipped)}: not run (no coordinator to kill); its runs go "
                      "on as without the fault", ""]
        curves = {}
        for mode in modes:
            for label, name in ((f"{mode}-n{cfg.fault_size}", f"{mode}, no fault"),
                                (f"{mode}-n{cfg.fault_size}-f{k}", f"{mode}, fault")):
                recs = [r for r in doc["records"] if r.get("cell") == label]
                counts = [window_counts(f["task_times"], cfg.duration_s)
                          for f in (run_figures(r, 0.0) for r in recs) if f]
                if counts:
                    curves[name] = [sum(c) / len(counts) for c in zip(*counts, strict=True)]
            base = {r["seed"]: run_figures(r, 0.0) for r in doc["records"]
                    if r.get("cell") == f"{mode}-n{cfg.fault_size}"}
            hit = {r["seed"]: run_figures(r, 0.0) for r in doc["records"]
                   if r.get("cell") == f"{mode}-n{cfg.fault_size}-f{k}"}
            effects = [fault_effect(base[s]["task_times"], hit[s]["task_times"], fault_s,
                                    cfg.duration_s)
                       for s in sorted(set(base) & set(hit))
                       if base[s] and hit[s]]
            if effects:
                lost = t_interval([e["tasks_lost"] for e in effects])
                rec = [e["recovery_s"] for e in effects]
                rec_text = ", ".join("never" if r is None else f"{r:g} s" for r in rec)
                lines.append(f"- {mode}: tasks lost against the no-fault run of the same seed "
                             f"{_fmt({'mean': lost[0], 'ci95': lost[1]}, 1)}; back within "
                             f"10 % of the no-fault rate after: {rec_text}")
        png = f"fault_{k}.png"
        plot_fault(cfg.output / png, curves, fault_s,
                   f"tasks per {WINDOW_S:g} s, {cfg.fault_size} robots, faults: {spec}")
        lines += ["", f"![fault curves {k}]({png})", ""]
    return lines


def print_summary(summaries: list[dict]) -> None:
    """The end-of-run table (rich; plain text off a terminal)."""
    from rich import box
    from rich.console import Console
    from rich.table import Table

    table = Table(title=f"{PROG}: mean ± 95 % interval", box=box.SIMPLE_HEAD, pad_edge=False)
    for h in ("mode", "size", "fault", "runs", "tasks/h", "time to task [s]", "p95 [s]",
              "collisions", "comm [B/s]", "coord [msg/s]", "RTF"):
        table.add_column(h, justify="right")
    for s in summaries:
        table.add_row(s["mode"], str(s["size"]), "yes" if s["fault"] else "-",
                      f"{s['runs_ok']}/{s['runs']}", _fmt(s["throughput"], 0),
                      _fmt(s["ttt_mean"], 1), _fmt(s["ttt_p95"], 1), _fmt(s["collisions"], 1),
                      _fmt(s["comm_bytes"], 0), _fmt(s["coord_msgs"], 2), _fmt(s["rtf"], 2))
    Console(width=None if sys.stdout.isatty() else 160).print(table)


# --------------------------------------------------------------------------------------- main
def experiment(cfg: ExperimentConfig, argv: list[str]) -> int:
    """Run every cell, then write the report; returns the exit code (0, 1 or 130)."""
    from swarm_bench.bench import (
        BenchConfig,
        BenchView,
        _write_json,
        finish_doc,
        new_doc,
        run_swarm_up,
        say_outcome,
        stop_on_signals,
    )

    out = cfg.output
    out.mkdir(parents=True, exist_ok=True)
    results = out / "experiment.json"
    cells = cfg.cells()
    doc = new_doc("experiment", PROG, SCHEMA_VERSION, argv, {
        "sizes": cfg.sizes, "duration_s": cfg.duration_s, "runs": cfg.runs, "seed": cfg.seed,
        "world": cfg.world, "modes": cfg.modes, "faults": cfg.faults,
        "fault_size": cfg.fault_size, "fault_times_s": cfg.fault_times,
        "fault_modes": cfg.fault_modes, "warmup_s": cfg.warmup_s,
        "processes": cfg.processes, "swarm_up": str(cfg.swarm_up)})
    with stop_on_signals() as stop:
        view = BenchView(tty=sys.stdout.isatty(), prog=PROG)
        view.say(f"{len(cells)} cells x {cfg.runs} runs of {cfg.duration_s:g} simulated s; "
                 f"report in {out}")
        try:
            for i, cell in enumerate(cells, start=1):
                if stop:
                    break
                view.say(f"cell {i}/{len(cells)}: {cell.mode}, {cell.size} robots"
                         f"{', faults: ' + cell.fault if cell.fault else ''}")
                bcfg = BenchConfig(sizes=(cell.size,), duration_s=cfg.duration_s,
                                   runs=cfg.runs, world=cfg.world, seed=cfg.seed,
                                   coordination=cell.mode, processes=cfg.processes,
                                   output=results, plot=out / "unused.png", baseline=False,
                                   run_dir=out / "runs" / cell.label, swarm_up=cfg.swarm_up,
                                   extra_args=("--faults", cell.fault) if cell.fault else ())
                bcfg.run_dir.mkdir(parents=True, exist_ok=True)
                for r in range(cfg.runs):
                    if stop:
                        break
                    rec = run_swarm_up(bcfg, cell.size, r, stop, view)
                    if rec["interrupted"]:
                        break
                    rec.update(cell=cell.label, mode=cell.mode, fault=cell.fault)
                    doc["records"].append(rec)
                    doc["summary"] = _summaries(cfg, doc["records"])
                    _write_json(results, doc)
        finally:
            view.close()
        failed = any(r["exit_code"] != EXIT_OK for r in doc["records"])
    code = finish_doc(doc, results, _summaries(cfg, doc["records"]), stop, failed)
    report = write_report(cfg, doc)
    print_summary(doc["summary"])
    print(f"{PROG}: report: {report}", flush=True)
    print(f"{PROG}: raw results: {results}", flush=True)
    say_outcome(PROG, stop, failed, f"{len(doc['records'])} finished runs", results)
    return code


def _summaries(cfg: ExperimentConfig, records: list[dict]) -> list[dict]:
    out = []
    for cell in cfg.cells():
        recs = [r for r in records if r.get("cell") == cell.label]
        if recs:
            out.append(summarize_cell(cell, recs, cfg.warmup_s))
    return out


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``swarm-experiment``; returns the exit code (0, 1, 2 or 130)."""
    from swarm_bench.bench import command_main

    return command_main(PROG, argv, lambda args: validate(build_parser().parse_args(args)),
                        experiment)


if __name__ == "__main__":
    sys.exit(main())
