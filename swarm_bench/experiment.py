"""``swarm-experiment``: decentralized against centralized coordination, by the protocol.

::

    swarm-experiment [--sizes 20,50,100] [--duration 900] [--runs 5] [--seed 0]
                     [--world slim_blockage] [--variants V,V] [--ablations V,V | --no-ablations]
                     [--ablation-size N] [--fault-spec SPEC ... | --no-faults] [--fault-size N]
                     [--warmup 300] [--output DIR | --resume DIR] [--shard I/N]
                     [--only BLOCK,BLOCK]
                     [--processes per-robot|K] [--swarm-up PATH]
    swarm-experiment report DIR [DIR ...] [--output DIR]
    swarm-experiment recheck DIR [--seed S] [--only BLOCK,BLOCK]
    swarm-experiment table DIR [DIR ...] [--output FILE]

A *variant* is a coordination mode plus a recorded set of overrides (:data:`VARIANTS`): flags of
``swarm-up`` (the coordinator's policy) and navigator parameters (written into a copy of
``params/navigator.yaml`` passed with ``--nav-params``). Every cell is a (variant, size, fault)
triple; every run of a cell is one seed, the same seeds in every variant:

- the main variants (``--variants``, default decentralized, centralized-scheduler and
  centralized-pipelined) at every ``--sizes``;
- the ablations (``--ablations``) at ``--ablation-size``;
- every ``--fault-spec`` (default :data:`DEFAULT_FAULTS`, after the warm-up) at ``--fault-size``
  in the main variants (a spec that kills the coordinator only in the centralized ones), with
  their no-fault runs at that size.

Each run is ``swarm-up --swarm-size N --world W --seed S --commanders --rtf 0 --duration D
--coordination M [overrides] [--faults SPEC]`` (:func:`swarm_bench.bench.run_swarm_up`), and its
record goes to ``DIR/records/<cell>-s<seed>.json`` as soon as it ends (``DIR/plan.json`` holds the
settings). ``--shard I/N`` runs the runs whose index in the plan's order is I-1 modulo N, so N
machines (or N sittings) share a sweep; ``--only main:50,service`` runs only those blocks of
the plan (the plan stays whole); ``--resume DIR`` skips the runs DIR already holds (ended well).
At the end, and by ``swarm-experiment report DIR...`` at any time, the report is
rebuilt from the records alone (:mod:`swarm_bench.experiment_report`): ``report.md``, figures
(PNG and SVG) and ``experiment.json`` (the settings, every record, the summaries and the paired
statistics), which ``report`` also reads back, so a committed report is rebuilt from its JSON.

Exit codes: 0 every run ended well, 1 a run failed (the experiment goes on), 2 bad flags,
130 interrupted (the finished runs are kept and reported).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from swarm_bench.experiment_plan import (  # noqa: F401 - the runner's public names
    ABLATIONS,
    MAIN_VARIANTS,
    METRICS_KEPT,
    PROG,
    RECORDS,
    VARIANTS,
    Cell,
    Plan,
    Variant,
    load_record,
    plan_from_settings,
    record_path,
    slim_record,
)
from swarm_common import cli
from swarm_common.errors import EXIT_OK, InputError
from swarm_common.faults import KILL_COORDINATOR
from swarm_up.args import default_run_dir

SCHEMA_VERSION = 2
DEFAULT_FAULTS = ("kill-robot:3@360", "kill-coordinator@360+30")
"""The protocol's fault kinds that decide the comparison (experiment_protocol.md, "Faults"): a
whole robot dead, and the coordinator dead then restarted 30 s later by its supervisor; both
60 s after the default 300 s warm-up."""


# ---------------------------------------------------------------------------------------- flags
def _variants(text: str) -> tuple[str, ...]:
    parts = tuple(p.strip() for p in text.split(",") if p.strip())
    bad = [p for p in parts if p not in VARIANTS]
    if bad or not parts:
        raise argparse.ArgumentTypeError(
            f"must be a comma-separated list of {', '.join(VARIANTS)}, got {text!r}")
    return tuple(dict.fromkeys(parts))


def _fault_spec(text: str) -> str:
    if not text.strip():
        raise argparse.ArgumentTypeError("must not be empty")
    return text.strip()


def _service_times(text: str) -> tuple[float, ...]:
    out = []
    for part in text.split(","):
        try:
            value = float(part)
        except ValueError:
            raise argparse.ArgumentTypeError(
                f"must be comma-separated seconds >= 0, e.g. 15,60, got {text!r}") from None
        if not (value >= 0.0 and value < float("inf")):
            raise argparse.ArgumentTypeError(
                f"must be comma-separated seconds >= 0, e.g. 15,60, got {text!r}")
        out.append(value)
    return tuple(dict.fromkeys(out))


BLOCKS = ("main", "ablation", "service", "fault")
"""The kinds of :func:`_blocks`: a plan's cells by role (``main`` takes a size: ``main:50``)."""


def _blocks(text: str) -> tuple[str, ...]:
    out = []
    for part in (p.strip() for p in text.split(",")):
        kind, _, size = part.partition(":")
        if kind not in BLOCKS or (size and (kind != "main" or not size.isdigit()
                                            or int(size) < 1)):
            raise argparse.ArgumentTypeError(
                f"must be comma-separated blocks of {', '.join(BLOCKS)} (main:N for one size), "
                f"e.g. main:50,service, got {part!r}")
        out.append(part)
    return tuple(dict.fromkeys(out))


def in_blocks(cell: Cell, blocks: tuple[str, ...]) -> bool:
    """Whether ``cell`` belongs to one of ``blocks`` (:func:`_blocks`; empty: every cell).

    ``main`` is the main variants' no-fault cells at every size (``main:N`` at size N only),
    ``ablation``, ``service`` and ``fault`` the cells of that role (the fault study's N-1 runs
    among ``fault``)."""
    if not blocks:
        return True
    return any(b == cell.role or (cell.role == "main" and b == f"main:{cell.size}")
               for b in blocks)


def _shard(text: str) -> tuple[int, int]:
    try:
        i, n = (int(x) for x in text.split("/"))
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be I/N, e.g. 2/4, got {text!r}") from None
    if not 1 <= i <= n:
        raise argparse.ArgumentTypeError(f"must be I/N with 1 <= I <= N, got {text!r}")
    return i, n


def build_parser() -> argparse.ArgumentParser:
    """The ``swarm-experiment`` argument parser (runs; ``report`` has :func:`report_parser`)."""
    from swarm_bench.bench import sweep_parser

    p = sweep_parser(
        PROG, "Compare decentralized with centralized coordination on the same world, seeds "
        "and sizes (with ablations and faults): runs swarm-up for every cell, keeps one record "
        "per run and writes a report directory (Markdown, PNG and SVG figures, JSON). "
        f"'{PROG} report DIR...' rebuilds the report from records without simulating; "
        f"'{PROG} recheck DIR' runs one seed of every cell again at this commit; "
        f"'{PROG} table DIR...' prints the headline table of reports.",
        "experiment", "runs", (20, 50, 100), 5,
        "runs per cell; run r uses seed S+r in every variant")
    p.set_defaults(duration=900.0)
    p.add_argument("--variants", type=_variants, default=MAIN_VARIANTS, metavar="V,V",
                   help=f"the variants run at every size (default: {','.join(MAIN_VARIANTS)}; "
                   f"all: {', '.join(VARIANTS)})")
    p.add_argument("--ablations", type=_variants, default=ABLATIONS, metavar="V,V",
                   help=f"variants run at --ablation-size only (default: {','.join(ABLATIONS)})")
    p.add_argument("--no-ablations", action="store_true", help="run no ablation cells")
    p.add_argument("--ablation-size", type=cli.positive_int, default=None, metavar="N",
                   help="swarm size of the ablations (default: 50 if in --sizes, else the "
                   "largest size)")
    p.add_argument("--fault-spec", type=_fault_spec, action="append", default=None,
                   metavar="SPEC", help="a fault scenario, passed to swarm-up as --faults SPEC "
                   "(repeatable; each is one more cell per main variant at --fault-size; a "
                   "spec that kills the coordinator runs only in centralized variants; a robot "
                   "may be a placement, @station, @approach or @hall, chosen per seed from "
                   "the no-fault run's ground truth at the fault's time, e.g. "
                   "kill-robot:@approach@360; "
                   f"default: {' and '.join(DEFAULT_FAULTS)})")
    p.add_argument("--fault-runs", type=cli.positive_int, default=None, metavar="R",
                   help="seeds of the fault study: the fault cells and their no-fault runs "
                   "(default: --runs)")
    p.add_argument("--fault-n-minus-1", action="store_true",
                   help="also run every fault variant with one robot fewer and no fault: is a "
                   "robot lost mid-run worse than one never there?")
    p.add_argument("--no-faults", action="store_true",
                   help="run no fault cells (only the sizes)")
    p.add_argument("--fault-size", type=cli.positive_int, default=None, metavar="N",
                   help="swarm size of the fault runs (default: as --ablation-size)")
    p.add_argument("--service-times", type=_service_times, default=(), metavar="S,S",
                   help="workstation service times [s] to run every variant of --variants "
                   "with at --service-size, besides the world's own (its main cells; a value "
                   "equal to it is dropped) (default: none)")
    p.add_argument("--service-size", type=cli.positive_int, default=None, metavar="N",
                   help="swarm size of the service-time cells (default: 50 if in --sizes, "
                   "else the largest size)")
    p.add_argument("--warmup", type=cli.non_negative_float, default=300.0, metavar="SEC",
                   help="simulated seconds left out of the throughput (default: %(default)g)")
    out = p.add_mutually_exclusive_group()
    out.add_argument("--output", type=Path, default=None, metavar="DIR",
                     help="report directory (default: experiment-<timestamp>/)")
    out.add_argument("--resume", type=Path, default=None, metavar="DIR",
                     help="go on with the experiment in DIR: skip the runs it holds (ended "
                     "well); its plan must be this one")
    p.add_argument("--shard", type=_shard, default=(1, 1), metavar="I/N",
                   help="run only slice I of N of the runs (run k of the plan's order when "
                   "k %% N == I-1); the slices of N machines or sittings merge with "
                   f"'{PROG} report' (default: 1/1)")
    p.add_argument("--only", type=_blocks, default=(), metavar="BLOCK,BLOCK",
                   help="run only the runs of these blocks of the plan: main (main:N for one "
                   "size), ablation, service, fault; the plan stays whole, so a sitting takes "
                   "the block it has time for and the others follow with --resume (default: "
                   "every block)")
    p.add_argument("--swarm-up", type=Path, default=None, metavar="PATH",
                   help="the swarm-up executable (default: the one beside this Python)")
    p.add_argument("--allow-dirty", action="store_true",
                   help="run although a tracked file differs from the commit (refused "
                   "otherwise); every record keeps the SHA-256 of 'git diff HEAD'")
    return p


def report_parser() -> argparse.ArgumentParser:
    """The ``swarm-experiment report`` argument parser."""
    p = cli.ArgumentParser(
        prog=f"{PROG} report", allow_abbrev=False,
        description="Rebuild an experiment's report (report.md, figures, experiment.json) from "
        "run records alone, without simulating: each DIR is an experiment directory (its "
        "plan.json and records/) or a report directory (its experiment.json); the records of "
        "several DIRs (shards, machines) are merged.",
        epilog="Exit codes: 0 written, 2 bad input (a DIR without records, plans that differ).")
    p.add_argument("dirs", type=Path, nargs="+", metavar="DIR", help="where the records are")
    p.add_argument("--output", type=Path, default=None, metavar="DIR",
                   help="where to write the report (default: the first DIR)")
    return p


@dataclass(frozen=True)
class ExperimentConfig:
    """The validated flags: the plan and how to run it."""

    plan: Plan
    output: Path
    resume: bool
    shard: tuple[int, int]
    only: tuple[str, ...]
    """Blocks of the plan to run (:func:`in_blocks`); empty: all."""
    processes: str | int | None
    swarm_up: Path
    git: dict
    """The code's commit as :func:`swarm_bench.bench.git_commit` read it (every record keeps
    it)."""


def validate(args: argparse.Namespace) -> ExperimentConfig:
    """Check what argparse cannot.

    Raises:
        InputError: the first bad flag (one line naming it).
    """
    from swarm_bench.bench import git_commit, swarm_up_path, world_arg

    world = world_arg(args.world)
    if args.warmup >= args.duration:
        raise InputError(f"--warmup: {args.warmup:g} s leaves nothing of --duration "
                         f"{args.duration:g} s")
    out = args.resume if args.resume is not None else (
        args.output if args.output is not None else default_run_dir(Path("."), "experiment-"))
    if args.resume is not None and not (args.resume / "plan.json").is_file():
        raise InputError(f"--resume: '{args.resume}' holds no experiment (no plan.json)")
    if out.exists() and not out.is_dir():
        raise InputError(f"--output: '{out}' exists and is not a directory")
    if not out.expanduser().resolve().parent.is_dir():
        raise InputError(f"--output: directory '{out.expanduser().resolve().parent}' "
                         "does not exist")
    if args.no_faults and args.fault_spec:
        raise InputError("--no-faults: not together with --fault-spec")
    ablations = () if args.no_ablations else tuple(
        v for v in args.ablations if v not in args.variants)
    middle = 50 if 50 in args.sizes else max(args.sizes)
    ablation_size = args.ablation_size or middle if ablations else None
    specs = () if args.no_faults else tuple(args.fault_spec or DEFAULT_FAULTS)
    fault_size = (args.fault_size or ablation_size or middle) if specs else None
    times, variants = [], []
    from swarm_bench.experiment_faults import placement_of, with_robot

    for spec in specs:
        placement_of(spec)  # an unknown placement: InputError
        faults = _parse_spec(with_robot(spec), fault_size, args.duration)
        times.append(min(f.at for f in faults))
        central = any(f.kind == KILL_COORDINATOR for f in faults)
        variants.append(tuple(v for v in args.variants
                              if VARIANTS[v].mode == "centralized" or not central))
        if not variants[-1]:
            raise InputError(f"--fault-spec: '{spec}' kills the coordinator, which none of "
                             "--variants has")
    from swarm_commander.route import world_service_time

    if args.service_size is not None and not args.service_times:
        raise InputError("--service-size: needs --service-times")
    own = world_service_time(world)
    service_times = tuple(s for s in args.service_times if s != own)
    plan = Plan(sizes=args.sizes, duration_s=args.duration, runs=args.runs, seed=args.seed,
                world=world, variants=args.variants, ablations=ablations,
                ablation_size=ablation_size, faults=specs, fault_size=fault_size,
                fault_times=tuple(times), fault_variants=tuple(variants),
                warmup_s=args.warmup, service_times=service_times,
                service_size=(args.service_size or middle) if service_times else None,
                fault_runs=args.fault_runs if specs else None,
                fault_n_minus_1=bool(args.fault_n_minus_1 and specs))
    if args.resume is not None:
        old = json.loads((args.resume / "plan.json").read_text()).get("settings", {})
        new = plan.settings()
        diff = [k for k in new if old.get(k) != json.loads(json.dumps(new[k]))]
        if diff:
            raise InputError(f"--resume: '{args.resume}' was planned with other settings "
                             f"({', '.join(diff)}); give the same flags")
    swarm_up = swarm_up_path(args.swarm_up)
    git = git_commit()
    if not args.allow_dirty and git.get("dirty"):
        raise InputError("--allow-dirty: the working tree differs from its commit; commit the "
                         "changes (every run from a clean commit) or give --allow-dirty")
    return ExperimentConfig(plan=plan, output=out.expanduser().resolve(),
                            resume=args.resume is not None, shard=args.shard,
                            only=args.only,
                            processes=args.processes, swarm_up=swarm_up, git=git)


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


def nav_params_file(out: Path, variant: Variant) -> Path | None:
    """The navigator parameter file of a variant with navigator overrides (written into
    ``out/params/``), or None without overrides."""
    if not variant.navigator:
        return None
    import yaml

    from swarm_common import paths

    doc = yaml.safe_load((paths.PARAMS_DIR / "navigator.yaml").read_text())
    params = doc["navigator"]["ros__parameters"]
    for key, value in variant.navigator:
        if key not in params:
            raise KeyError(f"variant {variant.name}: no navigator parameter {key!r}")
        params[key] = value
    path = out / "params" / f"{variant.name}.yaml"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(f"# params/navigator.yaml with the overrides of variant {variant.name}: "
                    f"{dict(variant.navigator)}\n" + yaml.safe_dump(doc, sort_keys=False))
    return path


def run_dir_of(out: Path, label: str, seed: int, size: int) -> Path:
    """Where the swarm-up run of a cell's seed keeps its files (its ``sim_summary.json``)."""
    return out / "runs" / f"{label}-s{seed}" / f"n{size}-r0"


def fault_for(out: Path, cell: Cell, seed: int, world: str) -> str:
    """The concrete ``--faults`` spec of a fault cell's run: a placed victim
    (:mod:`swarm_bench.experiment_faults`) read off the no-fault run of the same seed and
    variant: its record's ``victim_positions``, else its run directory's track.

    Raises:
        InputError: neither is in ``out``.
    """
    from swarm_bench.experiment_faults import (
        placed_times,
        positions_at,
        resolve_spec,
        time_key,
    )

    times = placed_times(cell.fault)
    if not times:
        return cell.fault
    from swarm_scene.poi import poi_for_world
    from swarm_scene.world import resolve_world

    poi = poi_for_world(resolve_world(world))
    docks = np.array([w.pose[:2] for w in poi.workstations], float).reshape(-1, 2)
    label = f"{cell.variant}-n{cell.size}"
    kept = (load_record(record_path(out, label, seed)) or {}).get("victim_positions") or {}
    if not all(time_key(t) in kept for t in times):
        summary = run_dir_of(out, label, seed, cell.size) / "sim_summary.json"
        try:
            kept = positions_at(summary, times)
        except InputError as exc:
            raise InputError(
                f"--fault-spec '{cell.fault}': the victim's place needs the no-fault run "
                f"'{label}' seed {seed} of this experiment, with its record's "
                f"victim_positions or its track ({exc}): run it first") from None
    return resolve_spec(cell.fault, kept, docks)


def placement_times(plan: Plan, cell: Cell) -> list[float]:
    """The times [s] simulated at which a run of ``cell`` places the victim of a fault cell:
    those of every placed fault of its variant at its size, if ``cell`` is that no-fault run
    (else empty)."""
    from swarm_bench.experiment_faults import placed_times

    if cell.fault or cell.label != f"{cell.variant}-n{cell.size}":
        return []
    return sorted({t for c in plan.cells() if c.fault and c.variant == cell.variant
                   and c.size == cell.size for t in placed_times(c.fault)})


def variant_args(out: Path, cell: Cell, fault: str | None = None) -> tuple[str, ...]:
    """The ``swarm-up`` flags a cell adds to the common command: the variant's overrides, the
    fault spec (``fault``: the concrete one, :func:`fault_for`) and the service time."""
    v = VARIANTS[cell.variant]
    args = list(v.swarm_up)
    params = nav_params_file(out, v)
    if params is not None:
        args += ["--nav-params", str(params)]
    if cell.fault:
        args += ["--faults", fault or cell.fault]
    if cell.service is not None:
        args += ["--service-time", f"{cell.service:g}"]
    return tuple(args)


ESTIMATE_CPU_MS = 7.0
"""[ms] CPU per robot per simulated second the plan's estimate assumes (all processes; the
ledger at 8d1a2bb measured 5.7 at 20 robots and 7.2 at 100 on slim_blockage,
docs/results/ledger.md)."""
ESTIMATE_START_S = 20.0  # [s] wall: a run's start and end besides 0.2 s per robot


def estimate_wall_s(plan: Plan, cells: list[Cell]) -> float:
    """[s] wall: a rough estimate of how long ``cells`` (one entry per run) take on this
    machine: each run's start and end plus its simulated duration at the real-time factor
    :data:`ESTIMATE_CPU_MS` and the CPU count allow."""
    cores = os.cpu_count() or 1
    total = 0.0
    for c in cells:
        cpu_per_sim_s = c.size * ESTIMATE_CPU_MS / 1000.0
        total += ESTIMATE_START_S + 0.2 * c.size + plan.duration_s * cpu_per_sim_s / cores
    return total


# --------------------------------------------------------------------------------------- main
def experiment(cfg: ExperimentConfig, argv: list[str]) -> int:
    """Run this shard's runs that are still missing, then write the report; returns the exit
    code (0, 1 or 130)."""
    import datetime

    from swarm_bench.bench import (
        BenchConfig,
        BenchView,
        _write_json,
        machine_info,
        run_swarm_up,
        say_outcome,
        stop_on_signals,
    )
    from swarm_bench.experiment_faults import positions_at
    from swarm_bench.experiment_report import write_report

    out = cfg.output
    (out / RECORDS).mkdir(parents=True, exist_ok=True)
    plan = cfg.plan
    _write_json(out / "plan.json", {"experiment": PROG, "schema_version": SCHEMA_VERSION,
                                    "settings": plan.settings()})
    runs = [(k, c, s) for k, (c, s) in enumerate(plan.runs_in_order())
            if k % cfg.shard[1] == cfg.shard[0] - 1 and in_blocks(c, cfg.only)]
    todo = [(k, c, s) for k, c, s in runs
            if not cfg.resume or (load_record(record_path(out, c.label, s)) or {}).get(
                "exit_code") != EXIT_OK]
    git, machine = cfg.git, machine_info()
    failed, finished = False, 0
    with stop_on_signals() as stop:
        view = BenchView(tty=sys.stdout.isatty(), prog=PROG)
        view.say(f"{len(plan.cells())} cells x {plan.runs} runs = {len(plan.runs_in_order())} "
                 f"runs of {plan.duration_s:g} simulated s; shard {cfg.shard[0]}/{cfg.shard[1]}"
                 f"{', blocks ' + ','.join(cfg.only) if cfg.only else ''}: "
                 f"{len(runs)} runs, {len(runs) - len(todo)} already done; records in "
                 f"{out / RECORDS}")
        view.say(f"estimate: about {estimate_wall_s(plan, [c for _, c, _ in todo]) / 3600:.1f} "
                 f"h for the {len(todo)} runs to do ({ESTIMATE_CPU_MS:g} ms of CPU per robot per "
                 f"simulated second over {os.cpu_count()} cores, plus {ESTIMATE_START_S:g} s "
                 "and 0.2 s per robot to start each run: a rough guide)")
        try:
            for i, (_k, cell, seed) in enumerate(todo, start=1):
                if stop:
                    break
                view.say(f"run {i}/{len(todo)}: {cell.variant}, {cell.size} robots, seed {seed}"
                         f"{', faults: ' + cell.fault if cell.fault else ''}"
                         f"{f', service time {cell.service:g} s' if cell.service else ''}")
                run_dir = out / "runs" / f"{cell.label}-s{seed}"
                run_dir.mkdir(parents=True, exist_ok=True)
                try:
                    fault = fault_for(out, cell, seed, plan.world) if cell.fault else None
                except InputError as exc:
                    view.say(f"run {i}/{len(todo)} skipped: {exc}")
                    failed = True
                    continue
                if fault and fault != cell.fault:
                    view.say(f"  the victim: {fault}")
                bcfg = BenchConfig(sizes=(cell.size,), duration_s=plan.duration_s, runs=1,
                                   world=plan.world, seed=seed, coordination=cell.mode,
                                   processes=cfg.processes, output=out / "unused.json",
                                   plot=out / "unused.png", baseline=False, run_dir=run_dir,
                                   swarm_up=cfg.swarm_up,
                                   extra_args=variant_args(out, cell, fault))
                started = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
                rec = run_swarm_up(bcfg, cell.size, 0, stop, view)
                if rec["interrupted"]:
                    break
                rec["started"] = started
                rec["finished"] = datetime.datetime.now().astimezone().isoformat(
                    timespec="seconds")
                failed |= rec["exit_code"] != EXIT_OK
                finished += 1
                record = slim_record(rec, cell, seed, git, machine)
                if fault and fault != cell.fault:
                    record["fault_resolved"] = fault
                if times := placement_times(plan, cell):
                    with contextlib.suppress(InputError):  # fault_for says so, if it matters
                        record["victim_positions"] = positions_at(
                            run_dir_of(out, cell.label, seed, cell.size) / "sim_summary.json",
                            times)
                _write_json(record_path(out, cell.label, seed), record)
        finally:
            view.close()
    code = 130 if stop else (1 if failed else EXIT_OK)
    summary = write_report([out], out)
    print(f"{PROG}: report: {summary['report']}", flush=True)
    print(f"{PROG}: records: {out / RECORDS} ({summary['records']} runs, "
          f"{summary['missing']} of the plan still missing)", flush=True)
    say_outcome(PROG, stop, failed, f"{finished} runs this shard finished (their records in "
                f"{out / RECORDS}; --resume {out} goes on)", out / "experiment.json")
    return code


def recheck_parser() -> argparse.ArgumentParser:
    """The ``swarm-experiment recheck`` argument parser."""
    p = cli.ArgumentParser(
        prog=f"{PROG} recheck", allow_abbrev=False,
        description="Run one seed of every cell of an experiment again at this checkout's "
        "commit and compare its task times with the records' (the protocol's condition for "
        "runs from several commits in one report); the re-runs go to DIR/recheck/ and the "
        "report, rebuilt, says how many were identical.",
        epilog="Exit codes: 0 every re-run identical, 1 some differ or failed, 2 bad input, "
        "130 interrupted.")
    p.add_argument("dir", type=Path, metavar="DIR", help="the experiment directory")
    p.add_argument("--seed", type=cli.non_negative_int, default=None, metavar="S",
                   help="the seed to run again (default: the plan's first)")
    p.add_argument("--only", type=_blocks, default=(), metavar="BLOCK,BLOCK",
                   help="re-run only the cells of these blocks: main (main:N for one size), "
                   "ablation, service, fault (default: every block)")
    p.add_argument("--swarm-up", type=Path, default=None, metavar="PATH",
                   help="the swarm-up executable (default: the one beside this Python)")
    p.add_argument("--allow-dirty", action="store_true",
                   help="run although a tracked file differs from the commit (its re-runs "
                   "keep the diff's SHA-256)")
    return p


def recheck_main(argv: list[str]) -> int:
    """``swarm-experiment recheck DIR``: one seed of every cell again, at this commit."""
    import datetime

    from swarm_bench.bench import (
        BenchConfig,
        BenchView,
        _write_json,
        git_commit,
        machine_info,
        run_swarm_up,
        stop_on_signals,
        swarm_up_path,
    )
    from swarm_bench.experiment_report import RECHECK, write_report

    args = recheck_parser().parse_args(argv)
    out = args.dir.expanduser().resolve()
    if not (out / "plan.json").is_file():
        raise InputError(f"DIR: '{args.dir}' holds no experiment (no plan.json)")
    plan = plan_from_settings(json.loads((out / "plan.json").read_text())["settings"])
    seed = plan.seed if args.seed is None else args.seed
    git = git_commit()
    if not args.allow_dirty and git.get("dirty"):
        raise InputError("--allow-dirty: the working tree differs from its commit; commit the "
                         "changes or give --allow-dirty")
    swarm_up = swarm_up_path(args.swarm_up)
    todo = []
    for cell in (c for c in plan.cells() if in_blocks(c, args.only)):
        rec = load_record(record_path(out, cell.label, seed))
        if rec is not None and rec.get("exit_code") == EXIT_OK:
            todo.append((cell, rec))
    if not todo:
        raise InputError(f"--seed: no run of seed {seed} in '{args.dir}' ended well")
    machine, failed = machine_info(), False
    with stop_on_signals() as stop:
        view = BenchView(tty=sys.stdout.isatty(), prog=f"{PROG} recheck")
        view.say(f"{len(todo)} cells, seed {seed}, at commit {git.get('commit')}")
        try:
            for i, (cell, rec) in enumerate(todo, start=1):
                if stop:
                    break
                view.say(f"re-run {i}/{len(todo)}: {cell.label}, seed {seed}")
                fault = rec.get("fault_resolved") or cell.fault or None
                bcfg = BenchConfig(sizes=(cell.size,), duration_s=plan.duration_s, runs=1,
                                   world=plan.world, seed=seed, coordination=cell.mode,
                                   processes=None, output=out / "unused.json",
                                   plot=out / "unused.png", baseline=False,
                                   run_dir=out / "recheck_runs" / f"{cell.label}-s{seed}",
                                   swarm_up=swarm_up,
                                   extra_args=variant_args(out, cell, fault))
                bcfg.run_dir.mkdir(parents=True, exist_ok=True)
                started = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
                run = run_swarm_up(bcfg, cell.size, 0, stop, view)
                if run["interrupted"]:
                    break
                run["started"] = started
                run["finished"] = datetime.datetime.now().astimezone().isoformat(
                    timespec="seconds")
                again = slim_record(run, cell, seed, git, machine)
                again["recheck"] = True
                (out / RECHECK).mkdir(exist_ok=True)
                _write_json(out / RECHECK / f"{cell.label}-s{seed}.json", again)
                same = (again["metrics"] or {}).get("task_times_s") == (
                    rec.get("metrics") or {}).get("task_times_s")
                failed |= not same
                view.say(f"  task times {'identical' if same else 'DIFFER'}")
        finally:
            view.close()
    summary = write_report([out], out)
    print(f"{PROG} recheck: report: {summary['report']}", flush=True)
    return 130 if stop else (1 if failed else EXIT_OK)


def report_main(argv: list[str]) -> int:
    """``swarm-experiment report DIR...``: rebuild the report from records (exit 0 or 2)."""
    from swarm_bench.experiment_report import write_report

    args = report_parser().parse_args(argv)
    for d in args.dirs:
        if not d.is_dir():
            raise InputError(f"DIR: '{d}' is not a directory")
    out = (args.output or args.dirs[0]).expanduser().resolve()
    out.mkdir(parents=True, exist_ok=True)
    summary = write_report(args.dirs, out)
    print(f"{PROG} report: {summary['report']} from {summary['records']} runs "
          f"({summary['missing']} of the plan missing)", flush=True)
    return EXIT_OK


def table_parser() -> argparse.ArgumentParser:
    """The ``swarm-experiment table`` argument parser."""
    p = cli.ArgumentParser(
        prog=f"{PROG} table", allow_abbrev=False,
        description="Print the headline table of one or more experiment reports (Markdown): "
        "one row per arm, world, swarm size and service time, with throughput, Jain's index "
        "and the robots without a task (mean ± 95 %% interval) and each arm's paired "
        "difference from decentralized with its Holm-corrected p, read from each DIR's "
        "experiment.json alone.",
        epilog="Exit codes: 0 written, 2 bad input (a DIR without a report).")
    p.add_argument("dirs", type=Path, nargs="+", metavar="DIR",
                   help="report directories (each with its experiment.json)")
    p.add_argument("--output", type=Path, default=None, metavar="FILE",
                   help="write the table to FILE (default: print it)")
    return p


def table_main(argv: list[str]) -> int:
    """``swarm-experiment table DIR...``: the headline table (exit 0 or 2)."""
    from swarm_bench.experiment_table import headline

    args = table_parser().parse_args(argv)
    text = headline(args.dirs)
    if args.output is None:
        print(text, end="", flush=True)
    else:
        if not args.output.expanduser().resolve().parent.is_dir():
            raise InputError(f"--output: directory '{args.output.parent}' does not exist")
        args.output.write_text(text)
    return EXIT_OK


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``swarm-experiment``; returns the exit code (0, 1, 2 or 130)."""
    from swarm_bench.bench import command_main
    from swarm_common.errors import run_cli

    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] == ["report"]:
        return run_cli(f"{PROG} report", lambda: report_main(args[1:]))
    if args[:1] == ["table"]:
        return run_cli(f"{PROG} table", lambda: table_main(args[1:]))
    if args[:1] == ["recheck"]:
        return run_cli(f"{PROG} recheck", lambda: recheck_main(args[1:]))
    return command_main(PROG, args, lambda a: validate(build_parser().parse_args(a)),
                        experiment)


if __name__ == "__main__":
    sys.exit(main())
