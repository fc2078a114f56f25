"""The data of ``swarm-experiment``: variants, cells, the plan and run records (pure).

:mod:`swarm_bench.experiment` (the runner) and :mod:`swarm_bench.experiment_report` (the report
from records alone) both build on this; neither imports the other at module level.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

from swarm_common.errors import InputError

PROG = "swarm-experiment"


@dataclass(frozen=True)
class Variant:
    """A coordination mode plus the overrides that make it (recorded with every run).

    Attributes:
        name: the variant's name (``--variants``, the figures' legend).
        mode: ``decentralized`` | ``centralized`` (swarm-up's ``--coordination``).
        swarm_up: more ``swarm-up`` flags (the coordinator's policy).
        navigator: navigator parameter overrides, (name, value) pairs.
        what: one line for the report.
    """

    name: str
    mode: str
    swarm_up: tuple[str, ...] = ()
    navigator: tuple[tuple[str, float], ...] = ()
    what: str = ""

    def overrides(self) -> dict:
        """The recorded overrides: ``{"swarm_up": [...], "navigator": {...}}``."""
        return {"swarm_up": list(self.swarm_up), "navigator": dict(self.navigator)}


VARIANTS = {v.name: v for v in (
    Variant("decentralized", "decentralized", what="every navigator decides; a holding robot "
            "takes another free workstation of its goal's kind within swap_range (2.5 m)"),
    Variant("decentralized-patience", "decentralized", navigator=(("patience_time", 120.0),),
            what="decentralized with an anti-starvation rule: a robot that has held 120 s for "
            "its goal no longer holds for the crowd rule, and for congestion only as a "
            "starving robot (patience_time 120)"),
    Variant("decentralized-no-swap", "decentralized", navigator=(("swap_range", 0.0),),
            what="decentralized, but a robot only ever docks at the workstation it was sent "
            "to (swap_range 0)"),
    Variant("centralized-scheduler", "centralized",
            ("--assignment", "nearest-free", "--waiting-spots", "near"),
            what="the coordinator sends a robot to the nearest free workstation of its kind, "
            "queues the rest at the world's waiting spots near the workstations"),
    Variant("centralized-pipelined", "centralized",
            ("--policy", "pipelined", "--queue-at", "holding", "--assignment", "nearest-free"),
            what="the coordinator books every robot a time window at a workstation from ETAs "
            "(hand-over by arrival) and sends it there at once; the queue at the workstation "
            "is the navigators' holding pattern, their queue rules on; nothing held from "
            "dispatch to arrival"),
    Variant("centralized-pipelined-spots", "centralized",
            ("--policy", "pipelined", "--queue-at", "spots", "--assignment", "nearest-free",
             "--waiting-spots", "near"),
            what="the pipelined coordinator, but a robot whose window does not begin on its "
            "arrival waits in line at a spot near its workstation (the navigators' queue rules "
            "off), sent on when first in line"),
    Variant("centralized-scheduler-hall", "centralized",
            ("--assignment", "nearest-free", "--waiting-spots", "hall"),
            what="the scheduler, but queued robots park in the hall (the spawn grid)"),
    Variant("centralized-fifo", "centralized",
            ("--assignment", "route", "--waiting-spots", "near"),
            what="the route's workstation only, first come first served, queues at the world's "
            "waiting spots near the workstations (the factorial's fixed goal, near spots)"),
    Variant("centralized-fifo-hall", "centralized",
            ("--assignment", "route", "--waiting-spots", "hall"),
            what="the route's workstation only, first come first served, queues parked in the "
            "hall (the coordinator before the scheduler)"),
)}
MAIN_VARIANTS = ("decentralized", "centralized-scheduler", "centralized-pipelined")
ABLATIONS = ("decentralized-no-swap", "centralized-fifo-hall", "centralized-scheduler-hall")


@dataclass(frozen=True)
class Cell:
    """One (variant, size, fault) cell.

    Attributes:
        variant: the variant's name.
        size: robots.
        fault: the ``--faults`` spec, or ``""`` for none.
        label: ``<variant>-n<size>`` (``-f<k>`` for the k-th fault spec, ``-w<S>`` for a
            service time of S s).
        role: ``main``, ``ablation``, ``service`` or ``fault``.
        service: [s] simulated: the workstations' service time (``swarm-up --service-time``);
            None: the world's own.
    """

    variant: str
    size: int
    fault: str
    label: str
    role: str = "main"
    service: float | None = None

    @property
    def mode(self) -> str:
        """The variant's coordination mode."""
        return VARIANTS[self.variant].mode


@dataclass(frozen=True)
class Plan:
    """What an experiment runs: the validated flags that decide its records.

    ``plan.json`` holds :meth:`settings`; a resumed experiment must have the same.
    """

    sizes: tuple[int, ...]
    duration_s: float
    runs: int
    seed: int
    world: str
    variants: tuple[str, ...]
    ablations: tuple[str, ...]
    ablation_size: int | None
    faults: tuple[str, ...]
    fault_size: int | None
    fault_times: tuple[float, ...]  # [s] simulated, one per spec of ``faults``
    fault_variants: tuple[tuple[str, ...], ...]  # the variants each spec runs in
    warmup_s: float
    service_times: tuple[float, ...] = ()  # [s] swept at service_size (besides the world's)
    service_size: int | None = None
    fault_runs: int | None = None  # seeds of the fault study's cells (None: ``runs``)
    fault_n_minus_1: bool = False  # also every fault variant with one robot fewer, no fault

    def settings(self) -> dict:
        """The plan as JSON-able settings (with every variant's overrides)."""
        used = dict.fromkeys((*self.variants, *self.ablations))
        return {"sizes": list(self.sizes), "duration_s": self.duration_s, "runs": self.runs,
                "seed": self.seed, "world": self.world, "variants": list(self.variants),
                "ablations": list(self.ablations), "ablation_size": self.ablation_size,
                "faults": list(self.faults), "fault_size": self.fault_size,
                "fault_times_s": list(self.fault_times),
                "fault_variants": [list(v) for v in self.fault_variants],
                "warmup_s": self.warmup_s,
                # only when swept: the settings of an experiment without stay as they were
                **({"service_times_s": list(self.service_times),
                    "service_size": self.service_size} if self.service_times else {}),
                **({"fault_runs": self.fault_runs} if self.fault_runs is not None else {}),
                **({"fault_n_minus_1": True} if self.fault_n_minus_1 else {}),
                "overrides": {v: {"mode": VARIANTS[v].mode, **VARIANTS[v].overrides(),
                                  "what": VARIANTS[v].what} for v in used}}

    def cells(self) -> list[Cell]:
        """Every cell, in run order: sizes ascending with every main variant, the ablations,
        the service times (every main variant at ``service_size``; the world's own service
        time is the main cell, run here if its size is not among the sizes), the fault runs'
        baselines (if their size is not among the sizes), then the faults."""
        out = [Cell(v, n, "", f"{v}-n{n}") for n in self.sizes for v in self.variants]
        labels = {c.label for c in out}
        if self.service_times:
            n = self.service_size
            out += [Cell(v, n, "", f"{v}-n{n}") for v in self.variants
                    if f"{v}-n{n}" not in labels]
            out += [Cell(v, n, "", f"{v}-n{n}-w{s:g}", "service", s)
                    for s in self.service_times for v in self.variants]
        labels = {c.label for c in out}
        if self.ablations and self.ablation_size is not None:
            out += [Cell(v, self.ablation_size, "", f"{v}-n{self.ablation_size}", "ablation")
                    for v in self.ablations if f"{v}-n{self.ablation_size}" not in labels]
        labels = {c.label for c in out}
        if self.faults:
            out += [Cell(v, self.fault_size, "", f"{v}-n{self.fault_size}")
                    for v in self.variants if f"{v}-n{self.fault_size}" not in labels]
        if self.faults and self.fault_n_minus_1 and self.fault_size > 1:
            n = self.fault_size - 1
            used = dict.fromkeys(v for vs in self.fault_variants for v in vs)
            out += [Cell(v, n, "", f"{v}-n{n}", "fault") for v in used
                    if f"{v}-n{n}" not in labels]
        for k, (spec, variants) in enumerate(zip(self.faults, self.fault_variants, strict=True),
                                             start=1):
            out += [Cell(v, self.fault_size, spec, f"{v}-n{self.fault_size}-f{k}", "fault")
                    for v in variants]
        return out

    def runs_in_order(self) -> list[tuple[Cell, int]]:
        """Every (cell, seed) run, in the plan's order: block by block (each size of the main
        variants, the ablations, each fault spec), seed by seed within a block, every variant
        of the block for one seed before the next seed, so that a sweep cut short leaves pairs
        (the same seed in every variant) rather than whole cells of one variant."""
        cells = self.cells()
        role = {"main": 0, "ablation": 1, "service": 2, "fault": 3}

        def block(c: Cell) -> tuple:
            return (role[c.role], c.size if c.role == "main" else 0, c.fault,
                    c.service or 0.0)

        order = sorted(((c, self.seed + r) for c in cells for r in range(self.runs_of(c))),
                       key=lambda cs: (block(cs[0]), cs[1], cells.index(cs[0])))
        return order

    def runs_of(self, cell: Cell) -> int:
        """Seeds of a cell: ``fault_runs`` for the fault study's cells (the faults, their
        no-fault runs at ``fault_size`` and the N-1 runs), ``runs`` for the others."""
        if self.fault_runs is None or not self.faults:
            return self.runs
        study = cell.role == "fault" or (cell.size == self.fault_size and not cell.fault
                                         and cell.role == "main")
        return max(self.runs, self.fault_runs) if study else self.runs


def plan_from_settings(settings: dict) -> Plan:
    """A :class:`Plan` back from :meth:`Plan.settings` (``plan.json``, ``experiment.json``).

    Raises:
        InputError: a key is missing or a variant unknown.
    """
    try:
        for v in (*settings["variants"], *settings["ablations"]):
            if v not in VARIANTS:
                raise InputError(f"unknown variant '{v}' in the records' plan")
        return Plan(sizes=tuple(settings["sizes"]), duration_s=float(settings["duration_s"]),
                    runs=int(settings["runs"]), seed=int(settings["seed"]),
                    world=str(settings["world"]), variants=tuple(settings["variants"]),
                    ablations=tuple(settings["ablations"]),
                    ablation_size=settings["ablation_size"], faults=tuple(settings["faults"]),
                    fault_size=settings["fault_size"],
                    fault_times=tuple(float(t) for t in settings["fault_times_s"]),
                    fault_variants=tuple(tuple(v) for v in settings["fault_variants"]),
                    warmup_s=float(settings["warmup_s"]),
                    service_times=tuple(float(s) for s in settings.get("service_times_s", ())),
                    service_size=settings.get("service_size"),
                    fault_runs=settings.get("fault_runs"),
                    fault_n_minus_1=bool(settings.get("fault_n_minus_1", False)))
    except (KeyError, TypeError, ValueError) as exc:
        raise InputError(f"the records' plan is malformed ({exc})") from None


# ------------------------------------------------------------------------------------ records
RECORDS = "records"
METRICS_KEPT = (
    "robots", "world", "seed", "coordination", "sim_time_s", "wall_time_s", "rtf",
    "tasks_completed", "goals_reached", "goals_aborted", "goals_at_another_workstation",
    "time_to_task_mean_s", "time_to_task_median_s", "time_to_task_p95_s", "task_times_s",
    "task_durations_s", "tasks_per_robot", "standstills", "standstill_s", "collisions",
    "min_separation_m", "holding_time_s", "late_ticks", "goal_wait_timeouts", "late_goals",
    "reproducible", "coordinator_wait_s", "reservation_conflicts", "coordinator_starts",
    "cpu_percent", "peak_rss_mb_per_robot", "restarts", "faults", "fault_log", "ended_by",
    "service_time_s", "waiting_s", "waiting_per_task_s", "coordinator_lapses")
"""The metrics a record keeps (``metrics.json`` has more: per-robot details, tables)."""


def slim_record(rec: dict, cell: Cell, seed: int, git: dict, machine: dict) -> dict:
    """The record of one run as ``records/<cell>-s<seed>.json`` keeps it.

    Args:
        rec: :func:`swarm_bench.bench.run_swarm_up`'s record.
        cell: its cell; seed: its seed; git, machine: where it ran.
    """
    m = rec.get("metrics") if isinstance(rec.get("metrics"), dict) else None
    slim = None
    if m is not None:
        slim = {k: m.get(k) for k in METRICS_KEPT}
        comm = m.get("comm") or {}
        slim["comm"] = {k: comm.get(k) for k in ("messages", "bytes", "messages_per_s",
                                                 "bytes_per_s", "by_topic")}
        per = m.get("per_robot") or {}
        robots = [per.get(ns) or {} for ns in sorted(per, key=lambda ns: (len(ns), ns))]
        slim["robot_tasks"] = [int(r.get("tasks") or 0) for r in robots]
        # per robot, in robot order: when each of its tasks was completed [s] simulated, and
        # the distance it drove [m] (the simulator's; None where unknown)
        slim["robot_task_times"] = [list(r.get("task_times_s") or []) for r in robots]
        slim["robot_distance_m"] = [r.get("distance_m") for r in robots]
        slim["robot_waiting_s"] = [r.get("waiting_s") for r in robots]
    keep = ("command", "exit_code", "error", "cpu_s", "cpu_per_robot")
    return {"label": cell.label, "variant": cell.variant, "mode": cell.mode,
            "size": cell.size, "fault": cell.fault, "role": cell.role, "seed": seed,
            **{k: rec.get(k) for k in keep}, "commit": git.get("commit"),
            "dirty": git.get("dirty"), "diff_sha256": git.get("diff_sha256"),
            "machine": machine, "started": rec.get("started"),
            "finished": rec.get("finished"), "metrics": slim}


def record_path(out: Path, label: str, seed: int) -> Path:
    """Where the record of one run lives."""
    return out / RECORDS / f"{label}-s{seed}.json"


def load_record(path: Path) -> dict | None:
    """A record file, or None if it is not one (unreadable, not JSON, no label)."""
    try:
        rec = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    return rec if isinstance(rec, dict) and "label" in rec and "seed" in rec else None
