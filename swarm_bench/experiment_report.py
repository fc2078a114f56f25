"""The report of ``swarm-experiment``, rebuilt from its run records alone.

:func:`write_report` reads the records of one or more directories (``plan.json`` and
``records/*.json`` of a sweep or a shard; or the ``experiment.json`` of a report), merges them
(one record per cell and seed; a run that ended well wins over one that did not, then the newer)
and writes, deterministically (the same records give the same bytes):

- ``experiment.json``: the plan's settings, every record, the cell summaries and the paired
  statistics;
- ``report.md``: the header (commands, commits, software, CPU, times), the primary measure
  with its paired tests, the ablations, the horizons, the secondary measures, Little's law,
  the faults, the threats to validity;
- the figures, PNG and SVG, each variant with a fixed colour and marker (:data:`STYLE`).

Statistics (:mod:`swarm_bench.experiment_stats`): mean and 95 % Student's-t interval across
seeds per cell; per pair of variants, the per-seed differences with their interval, the paired
t-test (primary) and Wilcoxon's signed-rank test (check); Holm's correction over the family of
claims of the report (every comparison of the primary measure, the main pairs of the secondary
measures).
"""

from __future__ import annotations

import json
from pathlib import Path

from swarm_bench.experiment_plan import (
    PROG,
    RECORDS,
    VARIANTS,
    Plan,
    load_record,
    plan_from_settings,
)
from swarm_bench.experiment_stats import (
    EQUIVALENCE_MARGIN,
    MEASURES,
    WINDOW_S,
    cumulative_lost,
    equivalence,
    factorial_2x2,
    fault_effect,
    holm,
    littles_law,
    paired,
    run_figures,
    t_interval,
    tasks_by,
    window_counts,
)
from swarm_common.errors import EXIT_OK, InputError

STYLE = {  # variant -> (colour, marker): fixed, so every figure reads alike
    "decentralized": ("#1f77b4", "o"),
    "decentralized-no-swap": ("#17becf", "v"),
    "decentralized-patience": ("#9467bd", "X"),
    "centralized-scheduler": ("#d62728", "s"),
    "centralized-scheduler-hall": ("#ff7f0e", "D"),
    "centralized-fifo-hall": ("#7f7f7f", "^"),
    "centralized-fifo": ("#8c564b", "<"),
    "centralized-pipelined": ("#2ca02c", "P"),
    "centralized-pipelined-spots": ("#bcbd22", "p"),
}
PRIMARY = "throughput"
CO_PRIMARY = ("jain", "idle_robots")
"""Fairness beside throughput: tested for the main pair in the same Holm family and shown in
the primary section (how evenly the tasks are shared, and the robots that finish none)."""
SECONDARY = ("ttt_km_median", "ttt_km_p95", "waiting_per_task", "comm_bytes")
"""Tested for the main pairs in the Holm family: the time to task after the warm-up with the
tasks still open at the end counted (Kaplan-Meier median and 95th percentile: a mean or
percentile of the completed tasks alone leaves out the robots that wait longest) and the waiting
per task from ground truth (the same definition in every mode; "holding + waiting" is not)."""
SECONDARY_UNCENSORED = ("ttt_mean", "ttt_p95", "holding_per_robot", "comm_bytes")
"""The secondary measures tested where a run's record lacks each robot's task times or the
waiting per task (older records, kept readable): the completed tasks' time to task and the
holding + waiting per robot."""
ALPHA = 0.05
ABLATION_PAIRS = (  # (A, B, what B differs from A in): a chain from decentralized to the
    # centralized scheduler, so the differences A - B add up to the whole gap
    ("decentralized", "decentralized-no-swap", "taking another workstation (decentralized)"),
    ("decentralized-no-swap", "centralized-fifo-hall",
     "the coordination itself (no goal flexibility on either side, queues in the hall)"),
    ("centralized-fifo-hall", "centralized-scheduler-hall", "the scheduler's assignment"),
    ("centralized-scheduler-hall", "centralized-scheduler",
     "waiting spots near the workstations instead of the hall"),
)
GAP = ("decentralized", "centralized-scheduler", "the whole gap")
CENTRAL_ARMS = ("centralized-scheduler", "centralized-pipelined")
"""The centralized arms decentralized is compared with, each on its own (the main pairs)."""
FACTORIALS = (  # (name, (factor A: level 0, level 1), (factor B: ...), cells [a][b])
    ("mode x goal flexibility", ("mode", "decentralized", "centralized"),
     ("goal", "fixed", "flexible"),
     (("decentralized-no-swap", "decentralized"),
      ("centralized-fifo", "centralized-scheduler"))),
    ("centralized: goal flexibility x queue placement", ("goal", "fixed", "flexible"),
     ("queues", "hall", "near"),
     (("centralized-fifo-hall", "centralized-fifo"),
      ("centralized-scheduler-hall", "centralized-scheduler"))),
)
"""The 2 x 2 designs the ablations form, tested as main effects and interaction
(:func:`~swarm_bench.experiment_stats.factorial_2x2`), each where all four cells ran."""
HORIZON = ("centralized-scheduler", "centralized-pipelined-spots",
           "reservation horizon: held from dispatch (reserve) against time windows (pipelined), "
           "nearest-free, near spots")
"""The reservation horizon's pair: the same assignment and waiting spots, a workstation held from
dispatch to arrival against booked by time window (variant, variant, what it isolates)."""


# ------------------------------------------------------------------------------------ loading
def load_dirs(dirs: list[Path]) -> tuple[Plan, dict, list[dict]]:
    """The merged plan, its settings and the records of ``dirs``.

    Raises:
        InputError: a directory without records, or plans that disagree on the world, the
            duration, the warm-up or the seeds.
    """
    settings, records = [], []
    for d in dirs:
        doc = d / "experiment.json"
        plan = d / "plan.json"
        recs = sorted((d / RECORDS).glob("*.json")) if (d / RECORDS).is_dir() else []
        if plan.is_file() and recs:
            settings.append(json.loads(plan.read_text())["settings"])
            records += [r for r in (load_record(p) for p in recs) if r is not None]
        elif doc.is_file():
            data = json.loads(doc.read_text())
            if not isinstance(data, dict) or "settings" not in data:
                raise InputError(f"DIR: '{doc}' is not an experiment report")
            settings.append(data["settings"])
            records += [r for r in data.get("records", []) if isinstance(r, dict)]
        else:
            raise InputError(f"DIR: '{d}' holds no records (no plan.json with records/, no "
                             "experiment.json)")
    first = settings[0]
    for other in settings[1:]:
        for key in ("world", "duration_s", "warmup_s", "seed", "runs"):
            if other.get(key) != first.get(key):
                raise InputError(f"DIR: the experiments differ in {key} ({first.get(key)} vs "
                                 f"{other.get(key)}): their records do not merge")
    merged = dict(first)
    for key in ("sizes", "variants", "ablations", "faults"):
        merged[key] = list(dict.fromkeys(x for s in settings for x in s.get(key, [])))
    merged["sizes"] = sorted(merged["sizes"])
    for key in ("fault_times_s", "fault_variants"):
        merged[key] = next((s[key] for s in settings if s.get("faults") == merged["faults"]),
                           first.get(key, []))
    merged["overrides"] = {k: v for s in settings for k, v in s.get("overrides", {}).items()}
    plan = plan_from_settings(merged)
    best: dict[tuple[str, int], dict] = {}
    for r in records:
        key = (r["label"], r["seed"])
        old = best.get(key)
        rank = (r.get("exit_code") == EXIT_OK, str(r.get("finished") or ""))
        if old is None or rank > (old.get("exit_code") == EXIT_OK,
                                  str(old.get("finished") or "")):
            best[key] = r
    return plan, merged, [best[k] for k in sorted(best)]


RECHECK = "recheck"
"""The directory of an experiment's re-runs at one commit (``swarm-experiment recheck``)."""


def load_rechecks(dirs: list[Path]) -> list[dict]:
    """The re-run records of ``dirs`` (``DIR/recheck/*.json``, or a report's ``rechecks``),
    by label and seed."""
    out = {}
    for d in dirs:
        d = Path(d)
        if (d / RECHECK).is_dir():
            found = [load_record(p) for p in sorted((d / RECHECK).glob("*.json"))]
        elif (d / "experiment.json").is_file():
            found = json.loads((d / "experiment.json").read_text()).get("rechecks", [])
        else:
            found = []
        for r in found:
            if isinstance(r, dict) and "label" in r:
                out[(r["label"], r["seed"])] = r
    return [out[k] for k in sorted(out)]


def recheck_table(records: list[dict], rechecks: list[dict]) -> list[dict]:
    """Per re-run: its cell, seed, the record's commit, the re-run's, and whether the task
    times (every robot's) are identical."""
    by = {(r["label"], r["seed"]): r for r in records}
    rows = []
    for rr in rechecks:
        rec = by.get((rr["label"], rr["seed"]))
        if rec is None:
            continue
        a, b = rec.get("metrics") or {}, rr.get("metrics") or {}
        same = (rr.get("exit_code") == EXIT_OK and a.get("task_times_s") == b.get("task_times_s")
                and a.get("robot_task_times") == b.get("robot_task_times"))
        rows.append({"label": rr["label"], "seed": rr["seed"], "commit": _commit_label(rec),
                     "recheck_commit": _commit_label(rr), "identical": bool(same)})
    return rows


# ---------------------------------------------------------------------------------- summaries
def cell_figures(plan: Plan, records: list[dict]) -> dict[str, dict[int, dict]]:
    """label -> seed -> :func:`run_figures` (runs that ended well only)."""
    out: dict[str, dict[int, dict]] = {}
    for r in records:
        f = run_figures(r, plan.warmup_s)
        if f is not None:
            out.setdefault(r["label"], {})[r["seed"]] = f
    return out


def summarize(plan: Plan, records: list[dict], figs: dict) -> list[dict]:
    """Per cell of the plan that has records: runs, mean and 95 % half-width of every measure,
    Little's law, the tasks by each horizon."""
    out = []
    horizons = horizons_of(plan)
    for cell in plan.cells():
        recs = [r for r in records if r["label"] == cell.label]
        if not recs:
            continue
        fs = figs.get(cell.label, {})
        row = {"label": cell.label, "variant": cell.variant, "mode": cell.mode,
               "size": cell.size, "fault": cell.fault, "role": cell.role, "runs": len(recs),
               "runs_ok": len(fs), "seeds": sorted(fs),
               "reproducible_runs": sum(1 for f in fs.values() if f["reproducible"]),
               "reservation_conflicts": sum(f["reservation_conflicts"] or 0
                                            for f in fs.values()),
               **({"service_s": cell.service} if cell.service is not None else {})}
        for key, _, _ in MEASURES:
            mean, half = t_interval([f[key] for f in fs.values() if f[key] is not None])
            row[key] = {"mean": mean, "ci95": half}
        laws = [littles_law(f["task_times"], f["task_durations"], f["robots"], plan.warmup_s,
                            f["sim_time"])["ratio"] for f in fs.values()]
        row["littles_ratio"] = t_interval([v for v in laws if v is not None])[0]
        row["horizons"] = {f"{h:g}": t_interval([tasks_by(f["task_times"], h)
                                                  for f in fs.values()])[0] for h in horizons}
        row["robots_without_task"] = [f["idle_robots"] for _, f in sorted(fs.items())]
        out.append(row)
    return out


def horizons_of(plan: Plan) -> list[float]:
    """The horizons tasks are counted by: every 300 simulated s, and the run's end."""
    hs = [float(h) for h in range(300, int(plan.duration_s), 300)]
    return [*hs, plan.duration_s]


MIN_CLAIM_SEEDS = 5  # the protocol's seeds per cell; a comparison over fewer claims nothing


def comparisons(plan: Plan, figs: dict) -> list[dict]:
    """Every paired comparison the report claims on, Holm-corrected together.

    The family: the primary and co-primary measures of decentralized against each centralized
    arm (:data:`CENTRAL_ARMS`) at every size and, where swept, at every service time, the
    primary measure of every ablation pair, the factorials' main effects and interactions and
    the reservation horizon (throughput and Jain's index), the secondary measures for the main
    pairs at every size (:data:`SECONDARY`, or :data:`SECONDARY_UNCENSORED` where a run's record
    lacks what they need; each pair once: the world's own service time at the service-time size
    is the main pair), and per fault: each variant's tasks after the fault without it against
    with it (does the fault cost tasks?), against one robot fewer where that ran, and the tasks
    lost of decentralized against each centralized arm (of the first two variants where the
    plan has not both main ones) where both ran it (does it cost one mode more?).
    Tasks lost are :func:`swarm_bench.experiment_stats.fault_effect`'s, per seed.
    """
    rows = []
    secondary = (SECONDARY if all(f.get("censored_ttt") for runs in figs.values()
                                  for f in runs.values())
                 else SECONDARY_UNCENSORED)
    main = [v for v in ("decentralized", "centralized-scheduler") if v in plan.variants]
    pairs = []
    against = [v for v in CENTRAL_ARMS if v in plan.variants]
    if len(main) == 2:
        for n in plan.sizes:
            pairs += [(f"{main[0]}-n{n}", f"{v}-n{n}", n, "main", "") for v in against]
    elif len(plan.variants) >= 2:
        for n in plan.sizes:
            pairs.append((f"{plan.variants[0]}-n{n}", f"{plan.variants[1]}-n{n}", n, "main", ""))
    if plan.ablation_size is not None:
        n = plan.ablation_size
        steps = [(f"{a}-n{n}", f"{b}-n{n}", n, "ablation", what)
                 for a, b, what in ABLATION_PAIRS]
        if any(x in figs and y in figs for x, y, *_ in steps):
            pairs += steps
            gap = (f"{GAP[0]}-n{n}", f"{GAP[1]}-n{n}")
            if not any(p[:2] == gap for p in pairs):  # else the main pair at n is the gap
                pairs.append((*gap, n, "ablation", GAP[2]))
    if plan.service_times and "decentralized" in plan.variants:
        n = plan.service_size
        for label, what in [("", "the world's service time"),
                            *((f"-w{t:g}", f"service time {t:g} s")
                              for t in plan.service_times)]:
            pairs += [(f"decentralized-n{n}{label}", f"{v}-n{n}{label}", n, "service", what)
                      for v in against  # a main pair is tested once, not again here
                      if not any(p[:2] == (f"decentralized-n{n}{label}", f"{v}-n{n}{label}")
                                 for p in pairs)]
    if plan.ablation_size is not None:
        n = plan.ablation_size
        if all(f"{v}-n{n}" in figs for v in HORIZON[:2]):
            pairs.append((f"{HORIZON[0]}-n{n}", f"{HORIZON[1]}-n{n}", n, "factorial",
                          HORIZON[2]))
    for a, b, n, role, what in pairs:
        if a not in figs or b not in figs:
            continue
        measures = {"main": (PRIMARY, *CO_PRIMARY, *secondary),
                    "service": (PRIMARY, *CO_PRIMARY),
                    "factorial": (PRIMARY, "jain")}.get(role, (PRIMARY,))
        for key in measures:
            st = paired({s: f[key] for s, f in figs[a].items()},
                        {s: f[key] for s, f in figs[b].items()})
            rows.append({"a": a, "b": b, "size": n, "role": role, "what": what,
                         "measure": key, **st})
    rows += _factorial_rows(plan, figs)
    lost_pairs = ([(main[0], v) for v in against] if len(main) == 2
                  else [tuple(plan.variants[:2])] if len(plan.variants) >= 2 else [])
    rows += _fault_comparisons(plan, figs, lost_pairs)
    adjusted = holm([r["p_t"] for r in rows])
    for r, p in zip(rows, adjusted, strict=True):
        r["p_holm"] = p
        r["claim"] = p is not None and p < ALPHA and r["n"] >= MIN_CLAIM_SEEDS
    return rows


def _factorial_rows(plan: Plan, figs: dict) -> list[dict]:
    """The :data:`FACTORIALS` at ``ablation_size`` where all four cells ran: per measure
    (throughput, Jain's index), each main effect and the interaction tested against 0 over the
    seeds (role ``factorial``)."""
    rows = []
    n = plan.ablation_size
    if n is None:
        return rows
    for name, fa, fb, cells in FACTORIALS:
        labels = [[f"{cells[i][j]}-n{n}" for j in (0, 1)] for i in (0, 1)]
        if not all(lab in figs for row in labels for lab in row):
            continue
        for key in (PRIMARY, "jain"):
            y = {(i, j): {s: f[key] for s, f in figs[labels[i][j]].items()}
                 for i in (0, 1) for j in (0, 1)}
            effects = factorial_2x2(y)
            for effect, what in (("A", f"{fa[0]}: {fa[2]} - {fa[1]}"),
                                 ("B", f"{fb[0]}: {fb[2]} - {fb[1]}"),
                                 ("AxB", f"{fa[0]} x {fb[0]} interaction")):
                zero = {s: 0.0 for s in effects[effect]}
                rows.append({"a": name, "b": what, "size": n, "role": "factorial",
                             "what": "", "measure": key, **paired(effects[effect], zero)})
    return rows


FAULT_AFTER = "tasks after the fault"
FAULT_LOST = "tasks lost to the fault"


def _fault_comparisons(plan: Plan, figs: dict,
                       lost_pairs: list[tuple[str, str]]) -> list[dict]:
    """The fault rows of :func:`comparisons` (role ``fault``, ``what`` the spec); the tasks
    lost are compared between the variants of each of ``lost_pairs``."""
    rows, n = [], plan.fault_size
    for k, (spec, fault_s) in enumerate(zip(plan.faults, plan.fault_times, strict=True),
                                        start=1):
        lost = {}
        for v in plan.variants:
            base, hit = figs.get(f"{v}-n{n}"), figs.get(f"{v}-n{n}-f{k}")
            if not base or not hit:
                continue
            after = {label: {s: float(sum(1 for t in f["task_times"] if t >= fault_s))
                             for s, f in runs.items()}
                     for label, runs in (("base", base), ("hit", hit))}
            st = paired(after["base"], after["hit"])
            mean_base = sum(after["base"].values()) / len(after["base"])
            rows.append({"a": f"{v}-n{n}", "b": f"{v}-n{n}-f{k}", "size": n, "role": "fault",
                         "what": spec, "measure": FAULT_AFTER, **st,
                         **equivalence(st["diffs"], EQUIVALENCE_MARGIN * mean_base)})
            lost[v] = {s: after["base"][s] - after["hit"][s]
                       for s in set(base) & set(hit)}
            fewer = figs.get(f"{v}-n{n - 1}")
            if fewer:  # a robot lost mid-run against one never there
                one_less = {s: float(sum(1 for t in f["task_times"] if t >= fault_s))
                            for s, f in fewer.items()}
                rows.append({"a": f"{v}-n{n - 1}", "b": f"{v}-n{n}-f{k}", "size": n,
                             "role": "fault", "what": f"{spec}, against {n - 1} robots",
                             "measure": FAULT_AFTER, **paired(one_less, after["hit"])})
        for a, b in lost_pairs:
            if a in lost and b in lost:
                # no "B vs A": a ratio of two losses near 0 (or below it) says nothing
                rows.append({"a": f"{a}-n{n}-f{k}", "b": f"{b}-n{n}-f{k}", "size": n,
                             "role": "fault", "what": spec, "measure": FAULT_LOST,
                             **paired(lost[a], lost[b]), "rel": None})
    return rows


# ------------------------------------------------------------------------------------ figures
def _plt():
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    plt.rcParams["svg.hashsalt"] = "swarm-experiment"  # fixed ids: the same SVG bytes
    return plt


def _save(fig, out: Path, stem: str) -> str:
    fig.savefig(out / f"{stem}.png", format="png", dpi=100, metadata={"Software": None})
    fig.savefig(out / f"{stem}.svg", format="svg", metadata={"Date": None, "Creator": None})
    import matplotlib.pyplot as plt

    plt.close(fig)
    return f"{stem}.png"


def _variants_in(summaries: list[dict]) -> list[str]:
    return [v for v in VARIANTS if any(s["variant"] == v for s in summaries)]


def plot_against_size(out: Path, stem: str, plan: Plan, summaries: list[dict], figs: dict,
                      key: str, label: str) -> str:
    """A measure against swarm size: every seed's point (small), the mean with its 95 %
    interval (error bar), one colour and marker per variant."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
    plain = [s for s in summaries if s["role"] in ("main", "ablation")]
    sizes = sorted({s["size"] for s in plain})
    vs = _variants_in(plain)
    for i, v in enumerate(vs):
        colour, marker = STYLE[v]
        rows = sorted((s for s in plain if s["variant"] == v and s[key]["mean"] is not None),
                      key=lambda s: s["size"])
        if not rows:
            continue
        dx = (i - (len(vs) - 1) / 2) * 0.012 * (max(sizes) - min(sizes) or 10)
        xs = [s["size"] + dx for s in rows]
        ax.errorbar(xs, [s[key]["mean"] for s in rows],
                    yerr=[s[key]["ci95"] or 0.0 for s in rows], color=colour, marker=marker,
                    capsize=4, label=v, linestyle="-" if len(rows) > 1 else "none")
        for s, x in zip(rows, xs, strict=True):
            pts = [f[key] for f in figs.get(s["label"], {}).values() if f[key] is not None]
            ax.scatter([x] * len(pts), pts, color=colour, marker=marker, s=12, alpha=0.45,
                       linewidths=0)
    ax.set_xticks(sizes)
    ax.set_xlabel("swarm size [robots]")
    ax.set_ylabel(label)
    ax.set_title(f"{label}: mean ± 95 % interval, points: seeds", fontsize=10)
    ax.grid(True, alpha=0.3)
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=8)
    return _save(fig, out, stem)


def _panels(plt, n: int):
    fig, axes = plt.subplots(1, n, figsize=(4.2 * n + 1.0, 3.8), constrained_layout=True,
                             squeeze=False)
    return fig, axes[0]


def _save_panels(fig, axes, sizes: list[int], xlabel: str, ylabel: str, out: Path,
                 stem: str) -> str:
    """Title each size's panel, label the axes, add a grid and the first panel's legend; save."""
    for ax, n in zip(axes, sizes, strict=True):
        ax.set_title(f"{n} robots", fontsize=10)
        ax.set_xlabel(xlabel)
        ax.grid(True, alpha=0.3)
    axes[0].set_ylabel(ylabel)
    axes[0].legend(fontsize=7)
    return _save(fig, out, stem)


def plot_tasks_over_time(out: Path, plan: Plan, summaries: list[dict], figs: dict) -> str:
    """Cumulative tasks over simulated time (mean over seeds), one panel per size, the
    warm-up marked: where the rate settles."""
    plt = _plt()
    plain = [s for s in summaries if s["role"] in ("main", "ablation")]
    sizes = sorted({s["size"] for s in plain})
    fig, axes = _panels(plt, len(sizes))
    step = 10.0
    grid = [step * k for k in range(int(plan.duration_s // step) + 1)]
    for ax, n in zip(axes, sizes, strict=True):
        for s in (s for s in plain if s["size"] == n):
            runs = figs.get(s["label"], {}).values()
            if not runs:
                continue
            mean = [sum(tasks_by(f["task_times"], t) for f in runs) / len(runs) for t in grid]
            colour, _ = STYLE[s["variant"]]
            ax.plot(grid, mean, color=colour, label=s["variant"])
        ax.axvline(plan.warmup_s, color="black", linestyle=":", linewidth=1.0,
                   label=f"warm-up {plan.warmup_s:g} s")
    return _save_panels(fig, axes, sizes, "simulated time [s]",
                        "tasks completed (mean over seeds)", out, "tasks_over_time")


def plot_ecdf(out: Path, plan: Plan, summaries: list[dict], figs: dict) -> str:
    """The distribution (ECDF) of time to task after the warm-up, every seed pooled."""
    plt = _plt()
    plain = [s for s in summaries if s["role"] in ("main", "ablation")]
    sizes = sorted({s["size"] for s in plain})
    fig, axes = _panels(plt, len(sizes))
    for ax, n in zip(axes, sizes, strict=True):
        for s in (s for s in plain if s["size"] == n):
            ds = sorted(d for f in figs.get(s["label"], {}).values()
                        for t, d in zip(f["task_times"], f["task_durations"], strict=False)
                        if t > plan.warmup_s)
            if not ds:
                continue
            colour, _ = STYLE[s["variant"]]
            ax.step(ds, [(i + 1) / len(ds) for i in range(len(ds))], where="post",
                    color=colour, label=s["variant"])
    return _save_panels(fig, axes, sizes, "time to task [s]",
                        "fraction of tasks (after the warm-up)", out, "time_to_task_ecdf")


def plot_tasks_per_robot(out: Path, plan: Plan, summaries: list[dict], figs: dict) -> str:
    """Tasks per robot over the whole run: a box per cell, every seed's robots pooled."""
    plt = _plt()
    plain = [s for s in summaries if s["role"] in ("main", "ablation")]
    fig, ax = plt.subplots(figsize=(max(6.4, 0.9 * len(plain) + 2), 4.2),
                           constrained_layout=True)
    data, labels, colours = [], [], []
    for s in sorted(plain, key=lambda s: (s["size"], list(VARIANTS).index(s["variant"]))):
        vals = [v for f in figs.get(s["label"], {}).values() for v in f["robot_tasks"]]
        if vals:
            data.append(vals)
            labels.append(f"{s['variant']}\n{s['size']}")
            colours.append(STYLE[s["variant"]][0])
    if data:
        box = ax.boxplot(data, patch_artist=True, widths=0.6)
        ax.set_xticks(range(1, len(labels) + 1), labels, fontsize=6, rotation=30)
        for patch, c in zip(box["boxes"], colours, strict=True):
            patch.set_facecolor(c)
            patch.set_alpha(0.5)
    ax.set_ylabel("tasks of a robot (whole run)")
    ax.set_title("tasks per robot (every robot of every seed)", fontsize=10)
    ax.grid(True, alpha=0.3, axis="y")
    return _save(fig, out, "tasks_per_robot")


def plot_standstill_map(out: Path, plan: Plan, summaries: list[dict], figs: dict,
                        size: int) -> str | None:
    """Where robots wait: robot-seconds of standstills >= 60 s (the simulator's episodes) per
    0.5 m cell over the map, summed over the seeds, one panel per variant at ``size``."""
    import numpy as np

    cells = [s for s in summaries if s["role"] in ("main", "ablation")
             and s["size"] == size]
    if not cells:
        return None
    plt = _plt()
    fig, axes = _panels(plt, len(cells))
    occ = _map_image(plan.world)
    for ax, s in zip(axes, cells, strict=True):
        eps = [e for f in figs.get(s["label"], {}).values() for e in f["standstills"]]
        if occ is not None:
            img, extent = occ
            ax.imshow(img, cmap="gray", extent=extent, origin="upper", alpha=0.6)
        if eps:
            xs = np.array([float(e["x"]) for e in eps])
            ys = np.array([float(e["y"]) for e in eps])
            ws = np.array([float(e["duration_s"]) for e in eps])
            if occ is not None:
                x0, x1, y0, y1 = occ[1]
            else:
                x0, x1, y0, y1 = xs.min() - 1, xs.max() + 1, ys.min() - 1, ys.max() + 1
            bins = [np.arange(x0, x1 + 0.5, 0.5), np.arange(y0, y1 + 0.5, 0.5)]
            h, xe, ye = np.histogram2d(xs, ys, bins=bins, weights=ws)
            h = np.ma.masked_where(h <= 0, h)
            mesh = ax.pcolormesh(xe, ye, h.T, cmap="magma_r", alpha=0.85)
            fig.colorbar(mesh, ax=ax, shrink=0.8, label="robot-s standing (all seeds)")
        ax.set_title(f"{s['variant']}, {size} robots", fontsize=9)
        ax.set_xlabel("x [m] (map)")
        ax.set_aspect("equal")
    axes[0].set_ylabel("y [m] (map)")
    return _save(fig, out, f"standstill_map_n{size}")


def _map_image(world: str):
    """The world's occupancy map as (image, extent) for imshow, or None."""
    try:
        from swarm_common import paths
        from swarm_scene.map_io import load_map
        from swarm_scene.world import resolve_world

        m = load_map(paths.default_map_for(resolve_world(world)))
    except (InputError, OSError, TypeError, ValueError):
        return None
    import numpy as np

    grid = np.asarray(m.data)
    h, w = grid.shape
    x0, y0 = float(m.origin[0]), float(m.origin[1])
    img = np.where(grid >= 50, 0.0, 1.0)[::-1]  # row 0 of the grid is y0: flip for imshow
    return img, (x0, x0 + w * m.resolution, y0, y0 + h * m.resolution)


def plot_standing_over_time(out: Path, plan: Plan, summaries: list[dict], figs: dict,
                            size: int) -> str | None:
    """Robots standing still (in an episode that lasts >= 60 s) over simulated time, mean over
    seeds: the queue lengths of both modes measured alike."""
    cells = [s for s in summaries if s["role"] in ("main", "ablation")
             and s["size"] == size]
    if not cells:
        return None
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2), constrained_layout=True)
    step = 10.0
    grid = [step * k for k in range(int(plan.duration_s // step) + 1)]
    for s in cells:
        runs = list(figs.get(s["label"], {}).values())
        if not runs:
            continue
        mean = [sum(sum(1 for e in f["standstills"]
                        if float(e["start_s"]) <= t < float(e["start_s"]) + float(e["duration_s"]))
                    for f in runs) / len(runs) for t in grid]
        colour, marker = STYLE[s["variant"]]
        ax.plot(grid, mean, color=colour, label=s["variant"])
    ax.axvline(plan.warmup_s, color="black", linestyle=":", linewidth=1.0, label="warm-up")
    ax.set_xlabel("simulated time [s]")
    ax.set_ylabel("robots standing still (episodes >= 60 s)")
    ax.set_title(f"queues: robots standing still, {size} robots (mean over seeds)", fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, out, f"standing_over_time_n{size}")


def plot_fault(out: Path, stem: str, curves: dict[str, tuple[str, list[float]]],
               fault_s: float, title: str) -> str:
    """Tasks per 30 s window over simulated time (mean over seeds), the fault marked."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2), constrained_layout=True)
    for name, (variant, counts) in curves.items():
        xs = [(i + 0.5) * WINDOW_S for i in range(len(counts))]
        colour, marker = STYLE[variant]
        ax.plot(xs, counts, color=colour, marker=marker, markersize=3, label=name,
                linestyle="--" if "no fault" in name else "-")
    ax.axvline(fault_s, color="red", linewidth=1.0, label=f"fault at {fault_s:g} s")
    ax.set_xlabel("simulated time [s]")
    ax.set_ylabel(f"tasks completed per {WINDOW_S:g} s")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, out, stem)


def plot_cumulative_lost(out: Path, stem: str, curves: dict[str, list], fault_s: float,
                         title: str) -> str:
    """Tasks lost to the fault by each time after it (no fault minus fault, same seed): the
    mean over seeds with its 95 % band, one line per variant."""
    plt = _plt()
    fig, ax = plt.subplots(figsize=(7.5, 4.2), constrained_layout=True)
    for variant, stats in curves.items():
        xs = [fault_s + (i + 1) * WINDOW_S for i in range(len(stats))]
        mean = [m if m is not None else float("nan") for m, _ in stats]
        half = [h if h is not None else 0.0 for _, h in stats]
        colour, marker = STYLE[variant]
        ax.plot(xs, mean, color=colour, marker=marker, markersize=3, label=variant)
        ax.fill_between(xs, [m - h for m, h in zip(mean, half, strict=True)],
                        [m + h for m, h in zip(mean, half, strict=True)], color=colour,
                        alpha=0.15, linewidth=0)
    ax.axhline(0.0, color="black", linewidth=0.8)
    ax.set_xlabel("simulated time [s]")
    ax.set_ylabel("tasks lost to the fault, cumulative")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7)
    return _save(fig, out, stem)


# ------------------------------------------------------------------------------------- report
def _fmt(stat: dict | None, digits: int) -> str:
    if not stat or stat.get("mean") is None:
        return "-"
    text = f"{stat['mean']:.{digits}f}"
    return text if stat.get("ci95") is None else f"{text} ± {stat['ci95']:.{digits}f}"


def _p(p: float | None) -> str:
    return "-" if p is None else ("< 0.001" if p < 0.001 else f"{p:.3f}")


def _cmd(argv) -> str:
    import shlex

    return " ".join(shlex.quote(str(a)) for a in argv)


def _commit_label(record: dict) -> str:
    """A record's commit as the report names it: ``<sha>``, ``<sha> (dirty)`` or, when the
    record keeps its diff's hash, ``<sha> (dirty, diff sha256 <first 12 digits>)``."""
    label = record.get("commit") or "?"
    if not record.get("dirty"):
        return label
    digest = record.get("diff_sha256")
    return f"{label} (dirty, diff sha256 {digest[:12]})" if digest else f"{label} (dirty)"


def _provenance(commits: list[str], checks: list[dict]) -> list[str]:
    """What the report says of runs from several commits (the protocol's provenance rule)."""
    if checks:
        same = [c for c in checks if c["identical"]]
        at = ", ".join(sorted({f"`{c['recheck_commit']}`" for c in checks}))
        differ = [f"{c['label']} seed {c['seed']}" for c in checks if not c["identical"]]
        return [f"- re-run at {at}: one seed of {len(checks)} cells; task times identical to "
                f"the records' in {len(same)} of {len(checks)}"
                + (f" (they differ in {', '.join(differ)})" if differ else "")]
    if len(commits) > 1:
        return [f"- runs from {len(commits)} commits and no re-run check (`{PROG} recheck`): "
                "the comparisons assume the commits between them change no simulated behaviour"]
    return []


def _header(plan: Plan, settings: dict, records: list[dict],
            checks: list[dict] = ()) -> list[str]:
    commits = sorted({_commit_label(r) for r in records})
    machines = {}
    for r in records:
        m = r.get("machine") or {}
        key = (m.get("cpu_model"), m.get("cores"), m.get("python"), m.get("ros_distro"),
               m.get("rclpy"), m.get("fastdds"), m.get("platform"))
        machines[key] = machines.get(key, 0) + 1
    started = min((r["started"] for r in records if r.get("started")), default="?")
    finished = max((r["finished"] for r in records if r.get("finished")), default="?")
    lines = ["## How this was made", "",
             "Every run (the seeds are the same in every variant):", "", "```bash",
             f"swarm-up --swarm-size N --world {Path(plan.world).stem} --seed S --commanders "
             f"--rtf 0 --duration {plan.duration_s:g} --coordination MODE [overrides] "
             "[--faults SPEC]", "```", "",
             "The sweep, in slices (`--shard I/N` on as many machines or sittings as there "
             "are; `--resume DIR` goes on where a slice stopped), and this report from the "
             "records alone:", "", "```bash",
             f"{PROG} --world {Path(plan.world).stem} --sizes "
             f"{','.join(map(str, plan.sizes))} --runs {plan.runs} --seed {plan.seed} "
             f"--duration {plan.duration_s:g} --warmup {plan.warmup_s:g} --variants "
             f"{','.join(plan.variants)}"
             + (f" --ablations {','.join(plan.ablations)} --ablation-size {plan.ablation_size}"
                if plan.ablations else " --no-ablations")
             + ("".join(f" --fault-spec {f}" for f in plan.faults) + f" --fault-size "
                f"{plan.fault_size}" if plan.faults else " --no-faults")
             + (f" --service-times {','.join(f'{t:g}' for t in plan.service_times)} "
                f"--service-size {plan.service_size}" if plan.service_times else "")
             + (f" --fault-runs {plan.fault_runs}" if plan.fault_runs is not None else "")
             + (" --fault-n-minus-1" if plan.fault_n_minus_1 else "")
             + " --resume DIR --shard I/N",
             f"{PROG} report DIR [DIR ...]", "```", "",
             f"- commit(s) of the runs: {', '.join(f'`{c}`' for c in commits)}",
             *_provenance(commits, list(checks)),
             f"- runs from {started} to {finished}"]
    for (cpu, cores, py, distro, rclpy, fastdds, plat), n in sorted(
            machines.items(), key=lambda kv: -kv[1]):
        lines.append(f"- machine ({n} runs): {cpu or '?'}, {cores} cores; Python {py}; ROS 2 "
                     f"{distro or '?'}, rclpy {rclpy}, Fast DDS {fastdds}; {plat}")
    lines += ["- every swarm-up command is in `experiment.json` (`records[i].command`)", "",
              "Variants (a coordination mode plus recorded overrides):", "",
              "| variant | mode | overrides | what |", "|---|---|---|---|"]
    overrides = settings.get("overrides", {})
    for name in sorted(overrides, key=lambda v: list(VARIANTS).index(v)):
        o = overrides[name]
        ov = " ".join(o.get("swarm_up", [])) + "".join(
            f" {k}={v:g}" for k, v in (o.get("navigator") or {}).items())
        lines.append(f"| {name} | {o.get('mode')} | `{ov.strip() or '-'}` | {o.get('what')} |")
    return lines + [""]


def build_report(plan: Plan, settings: dict, records: list[dict], summaries: list[dict],
                 stats: list[dict], figures: dict[str, str], checks: list[dict] = ()) -> str:
    """The Markdown of the report (deterministic in its inputs)."""
    world = Path(plan.world).stem
    lines = [f"# Decentralized vs centralized coordination: {world}", ""]
    lines += _header(plan, settings, records, checks)
    expected = len(plan.runs_in_order())
    ok = sum(s["runs_ok"] for s in summaries)
    repro = sum(s["reproducible_runs"] for s in summaries)
    lines += [f"**Runs.** {len(records)} of the plan's {expected} runs are here, {ok} ended "
              f"well, {repro} reproducible (their simulated figures depend on the seed alone: "
              "no late tick, goal-wait timeout, late goal or restart but the faults'). CPU and "
              "RTF depend on the machine's load; everything else on the seed.", ""]
    if len(records) < expected:
        lines += [f"**This report is partial**: {expected - len(records)} runs of the plan are "
                  "still missing; a cell with fewer than 5 seeds claims nothing.", ""]
    plain = [s for s in summaries if s["role"] in ("main", "ablation")]
    lines += _primary_section(plan, plain, stats, figures)
    lines += _service_section(plan, summaries, records, stats, figures)
    lines += _secondary_section(plan, plain, stats, figures)
    lines += _littles_section(summaries)
    lines += _fault_section(plan, summaries, figures, stats, records)
    lines += _threats(plan)
    return "\n".join(lines) + "\n"


def _primary_section(plan: Plan, plain: list[dict], stats: list[dict],
                     figures: dict[str, str]) -> list[str]:
    """Throughput after the warm-up: the table, its figures, the paired tests, the ablations'
    shares and the horizons."""
    lines = ["## Primary measures: throughput after the warm-up, and fairness", "",
             f"Tasks completed per simulated hour after the first {plan.warmup_s:g} s (the "
             "warm-up: the tasks-over-time figure shows the rate settled by then). Mean ± "
             "half-width of the 95 % interval across seeds (Student's t).", ""]
    vs = _variants_in(plain)
    sizes = sorted({s["size"] for s in plain})
    lines += ["| variant | " + " | ".join(f"{n} robots" for n in sizes) + " |",
              "|---|" + "---|" * len(sizes)]
    for v in vs:
        cells = {s["size"]: s for s in plain if s["variant"] == v}
        lines.append(f"| {v} | " + " | ".join(
            f"{_fmt(cells[n]['throughput'], 0)} ({cells[n]['runs_ok']})" if n in cells else ""
            for n in sizes) + " |")
    lines += ["", "(in brackets: seeds)", "", f"![throughput]({figures['throughput']})", "",
              f"![tasks over time]({figures['tasks_over_time']})", ""]
    lines += ["Fairness beside it: Jain's index of the tasks per robot over the whole run "
              "(1: every robot completed as many; 1/N: one robot completed them all) and the "
              "robots that completed no task, mean ± 95 % interval across seeds.", "",
              "| variant | " + " | ".join(f"{n} robots: Jain's index, without a task"
                                         for n in sizes) + " |",
              "|---|" + "---|" * len(sizes)]
    for v in vs:
        cells = {s["size"]: s for s in plain if s["variant"] == v}
        lines.append(f"| {v} | " + " | ".join(
            f"{_fmt(cells[n]['jain'], 3)}, {_fmt(cells[n]['idle_robots'], 1)}"
            if n in cells else "" for n in sizes) + " |")
    lines += [""]
    lines += _stats_table(stats, "main", "Paired differences, main variants",
                          (PRIMARY, *CO_PRIMARY))
    lines += _stats_table(stats, "ablation", "Ablations: how much of the gap each factor "
                          f"explains ({plan.ablation_size} robots)", (PRIMARY,))
    factorial = _factorial_table(stats)
    lines += factorial or _shares(stats)  # a factorial's effects, else the chain's shares
    lines += _horizons(plan, plain)
    return lines


def own_service_time(plan: Plan, records: list[dict]) -> float:
    """[s] the world's own service time, as the runs of the main cells at ``service_size``
    recorded it (0 where none did)."""
    for r in records:
        m = r.get("metrics") or {}
        if r.get("role") == "main" and r.get("size") == plan.service_size \
                and m.get("service_time_s") is not None:
            return float(m["service_time_s"])
    return 0.0


def service_rows(plan: Plan, summaries: list[dict], records: list[dict]
                 ) -> dict[str, dict[float, dict]]:
    """variant -> service time [s] -> its summary at ``service_size`` (the world's own: the
    main cell)."""
    own = own_service_time(plan, records)
    out: dict[str, dict[float, dict]] = {}
    for s in summaries:
        if s["fault"] or s["size"] != plan.service_size or s["role"] not in ("main", "service"):
            continue
        out.setdefault(s["variant"], {})[s.get("service_s", own)] = s
    return out


def plot_service(out: Path, plan: Plan, rows: dict[str, dict[float, dict]], figs: dict) -> str:
    """Throughput and Jain's index against the service time: mean ± 95 % interval, points:
    seeds; one line per variant."""
    plt = _plt()
    fig, axes = _panels(plt, 2)
    times = sorted({t for r in rows.values() for t in r})
    span = (max(times) - min(times)) or 10.0
    for ax, key, label in ((axes[0], "throughput", "throughput [tasks/h]"),
                           (axes[1], "jain", "Jain's index of tasks per robot")):
        vs = [v for v in VARIANTS if v in rows]
        for i, v in enumerate(vs):
            colour, marker = STYLE[v]
            pts = sorted((t, s) for t, s in rows[v].items() if s[key]["mean"] is not None)
            if not pts:
                continue
            dx = (i - (len(vs) - 1) / 2) * 0.012 * span
            xs = [t + dx for t, _ in pts]
            ax.errorbar(xs, [s[key]["mean"] for _, s in pts],
                        yerr=[s[key]["ci95"] or 0.0 for _, s in pts], color=colour,
                        marker=marker, capsize=4, label=v)
            for (_, s), x in zip(pts, xs, strict=True):
                seeds = [f[key] for f in figs.get(s["label"], {}).values() if f[key] is not None]
                ax.scatter([x] * len(seeds), seeds, color=colour, marker=marker, s=12,
                           alpha=0.45, linewidths=0)
        ax.set_xticks(times)
        ax.set_xlabel("workstation service time [s]")
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"{plan.service_size} robots: mean ± 95 % interval, points: seeds",
                 fontsize=10)
    return _save(fig, out, "service_time")


def _service_section(plan: Plan, summaries: list[dict], records: list[dict],
                     stats: list[dict], figures: dict[str, str]) -> list[str]:
    """The service-time sweep: throughput and fairness per variant and service time, and the
    paired tests of decentralized against each centralized arm at each."""
    if not plan.service_times:
        return []
    rows = service_rows(plan, summaries, records)
    times = sorted({t for r in rows.values() for t in r})
    own = own_service_time(plan, records)
    lines = ["## Service time: when each mode wins", "",
             f"Every robot stays docked at a workstation it reached for the service time "
             f"before it leaves (the workstation occupied meanwhile); {plan.service_size} "
             f"robots; {own:g} s is the world's own (the main cells). Throughput after the "
             "warm-up; Jain's index and the robots without a task over the whole run; mean ± "
             "95 % interval across seeds (in brackets: seeds).", "",
             "| variant | " + " | ".join(f"{t:g} s: throughput, Jain, without a task"
                                        for t in times) + " |",
             "|---|" + "---|" * len(times)]
    for v in [v for v in VARIANTS if v in rows]:
        lines.append(f"| {v} | " + " | ".join(
            f"{_fmt(rows[v][t]['throughput'], 0)}, {_fmt(rows[v][t]['jain'], 3)}, "
            f"{_fmt(rows[v][t]['idle_robots'], 1)} ({rows[v][t]['runs_ok']})"
            if t in rows[v] else "" for t in times) + " |")
    lines += [""]
    if "service_time" in figures:
        lines += [f"![service time]({figures['service_time']})", ""]
    own_pairs = [dict(r, role="service", what="the world's service time") for r in stats
                 if r["role"] == "main" and r["size"] == plan.service_size
                 and r["measure"] in (PRIMARY, *CO_PRIMARY)]  # tested once, as main pairs
    lines += _stats_table(own_pairs + [r for r in stats if r["role"] == "service"], "service",
                          "Paired differences by service time", (PRIMARY, *CO_PRIMARY))
    return lines


def _secondary_section(plan: Plan, plain: list[dict], stats: list[dict],
                       figures: dict[str, str]) -> list[str]:
    """The secondary measures: their table and paired tests, their figures, where robots wait
    and the robots without a task."""
    lines = ["## Secondary measures", "",
             "Mean ± 95 % interval across seeds; the paired tests of the main pair are in the "
             "table after.", ""]
    cols = sorted(plain, key=lambda s: (s["size"], list(VARIANTS).index(s["variant"])))
    zero = []
    lines += ["| measure | " + " | ".join(f"{s['variant']} {s['size']}" for s in cols) + " |",
              "|---|" + "---|" * len(cols)]
    for key, label, digits in MEASURES:
        vals = [s[key]["mean"] for s in cols if s[key]["mean"] is not None]
        if not vals:
            continue  # no run measured it (records from before the measure)
        if all(v == 0 for v in vals):
            zero.append(label)
        lines.append(f"| {label} | " + " | ".join(_fmt(s[key], digits) for s in cols) + " |")
    lines += [""]
    if zero:
        lines += [f"Zero in every run (so not plotted): {', '.join(zero)}.", ""]
    lines += _stats_table(stats, "main", "Paired differences of the secondary measures",
                          None)
    for key in ("ttt_mean", "holding_per_robot", "comm_bytes", "rtf", "cpu_per_robot_ms",
                "time_to_task_ecdf", "tasks_per_robot"):
        if key in figures:
            lines += [f"![{key}]({figures[key]})", ""]
    lines += ["Where robots wait: the simulator's standstills of 60 s or more (a robot within "
              "0.1 m of where it stopped), as robot-seconds per 0.5 m cell summed over the "
              "seeds, and how many robots stand so over time; the same measure in both modes "
              "(the decentralized holding pattern and the coordinator's waiting spots alike).",
              ""]
    for n in plan.sizes:
        for key in (f"standstill_map_n{n}", f"standing_over_time_n{n}"):
            if key in figures:
                lines += [f"![{key}]({figures[key]})", ""]
    lines += ["Robots that never completed a task are counted in every throughput (they are "
              "part of the swarm) and listed per seed:", "",
              "| cell | robots without a task, per seed |", "|---|---|"]
    lines += [f"| {s['label']} | {', '.join(str(x) for x in s['robots_without_task'])} |"
              for s in plain]
    return lines


def _littles_section(summaries: list[dict]) -> list[str]:
    """Little's law as a sanity check of every cell."""
    lines = ["", "## Sanity check: Little's law", "",
             "After the warm-up every robot always has a task, so λ·W (tasks per second × "
             "mean time to task) should be near N; tasks still open at the end are censored, "
             "so the ratio λ·W / N stays a little below 1.", "",
             "| cell | N | λ·W / N |", "|---|---|---|"]
    for s in summaries:
        ratio = s["littles_ratio"]
        lines.append(f"| {s['label']} | {s['size']} | "
                     f"{'-' if ratio is None else f'{ratio:.2f}'} |")
    return lines + [""]


def _threats(plan: Plan) -> list[str]:
    """The threats to validity."""
    return ["## Threats to validity", "",
            "- One machine type with 2 cores; CPU and RTF figures depend on its load (other "
            "work ran beside some runs), the simulated figures do not.",
            "- Simulated perfect odometry and lidar; one robot model.",
            f"- {len({Path(plan.world).stem})} world in this report; the other world's report "
            "is beside it.",
            "- The centralized policy is one reasonable scheduler (nearest free workstation "
            "of the kind, queue order for moving up, the nearest waiter for a freed "
            "workstation), not an optimal one; the decentralized navigator's parameters were "
            "tuned on slim_blockage (the thesis' world), the coordinator's were not tuned.",
            "- The waiting spots near the workstations are few where the world is narrow "
            "(slim_blockage: nine beside the blockage); the rest of a long queue parks in "
            "the hall.",
            "- Standstill maps and queue curves count only episodes of 60 s or more.",
            "- Communication counts serialized message bytes, not DDS headers, discovery or "
            "acknowledgements.", ""]


def _stats_table(stats: list[dict], role: str, title: str,
                 measures: tuple[str, ...] | None) -> list[str]:
    """The paired tests of ``role`` for ``measures`` (None: every measure but the primary and
    co-primary ones)."""
    rows = [r for r in stats if r["role"] == role
            and (r["measure"] in measures if measures else
                 r["measure"] not in (PRIMARY, *CO_PRIMARY))]
    if not rows:
        return []
    label = {k: lab for k, lab, _ in MEASURES}
    places = {k: d for k, _, d in MEASURES}
    out = [f"### {title}", "",
           "A − B per seed: mean and 95 % interval; p: paired t-test (two-sided; the primary "
           "test), Wilcoxon signed-rank (a check: with 5 seeds it cannot go below 0.0625), "
           "and t's p after Holm's correction over every comparison of this report. A "
           f"difference is claimed where Holm's p < {ALPHA:g}.", "",
           "| A | B | measure | seeds | A − B | B vs A | p (t) | p (Wilcoxon) | p (Holm) | "
           "claim |", "|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        digits = 0 if r["measure"] in ("throughput", "comm_bytes") else max(
            1, places.get(r["measure"], 1))
        diff = _fmt({"mean": r["diff"], "ci95": r["ci95"]}, digits)
        rel = "-" if r["rel"] is None else f"{100 * r['rel']:+.0f} %"
        claim = (("**yes**" if r["claim"] else "no") if r["n"] >= MIN_CLAIM_SEEDS
                 else f"no (< {MIN_CLAIM_SEEDS} seeds)")
        what = f" ({r['what']})" if r["what"] else ""
        out.append(f"| {r['a']} | {r['b']}{what} | {label.get(r['measure'], r['measure'])} | "
                   f"{r['n']} | {diff} | {rel} | {_p(r['p_t'])} | {_p(r['p_wilcoxon'])} | "
                   f"{_p(r['p_holm'])} | {claim} |")
    return out + [""]


def _factorial_table(stats: list[dict]) -> list[str]:
    """The ablations as factorial designs: main effects and interactions, and the reservation
    horizon, each with its interval and its tests (in the report's Holm family)."""
    rows = [r for r in stats if r["role"] == "factorial"]
    if not rows:
        return []
    label = {k: lab for k, lab, _ in MEASURES}
    out = ["### Ablations as a factorial", "",
           f"At {rows[0]['size']} robots. Each 2 x 2 design's main effects (one factor's "
           "second level minus its first, averaged over the other factor's levels) and its "
           "interaction (the first factor's effect at the other's second level minus at its "
           "first), per seed, tested against 0 (paired t, Holm over the whole report); the "
           "reservation horizon as the difference of its two arms. No shares of a chain: "
           "they depend on the chain's order.", "",
           "| design | effect | measure | seeds | estimate | p (t) | p (Holm) | claim |",
           "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        digits = 0 if r["measure"] == PRIMARY else 3
        if r["what"]:  # the horizon: A - B of two arms
            design, effect = r["what"], f"{r['a']} - {r['b']}"
        else:
            design, effect = r["a"], r["b"]
        claim = (("**yes**" if r["claim"] else "no") if r["n"] >= MIN_CLAIM_SEEDS
                 else f"no (< {MIN_CLAIM_SEEDS} seeds)")
        out.append(f"| {design} | {effect} | {label.get(r['measure'], r['measure'])} | "
                   f"{r['n']} | {_fmt({'mean': r['diff'], 'ci95': r['ci95']}, digits)} | "
                   f"{_p(r['p_t'])} | {_p(r['p_holm'])} | {claim} |")
    return out + [""]


def _shares(stats: list[dict]) -> list[str]:
    """The ablation chain's steps as shares of the whole gap (they add up to it)."""
    rows = {r["what"]: r for r in stats if r["role"] == "ablation" and r["measure"] == PRIMARY}
    steps_n = {r["size"] for r in rows.values()}
    gap = rows.get(GAP[2]) or next(
        (r for r in stats if r["role"] == "main" and r["measure"] == PRIMARY
         and r["size"] in steps_n and (r["a"].rsplit("-n", 1)[0], r["b"].rsplit("-n", 1)[0])
         == GAP[:2]), None)
    steps = [rows.get(what) for _, _, what in ABLATION_PAIRS]
    if gap is None or gap["diff"] in (None, 0) or any(r is None or r["diff"] is None
                                                      for r in steps):
        return []
    parts = [f"{r['what']} {r['diff']:+.0f} tasks/h ({100 * r['diff'] / gap['diff']:.0f} %)"
             for r in steps]
    return ["The chain decentralized → no swap → centralized FIFO in the hall → the scheduler in "
            "the hall → the scheduler with near spots adds up to the whole gap of "
            f"{gap['diff']:+.0f} tasks/h (mean over the seeds all five variants share): "
            + "; ".join(parts) + ".", ""]


def _horizons(plan: Plan, plain: list[dict]) -> list[str]:
    hs = horizons_of(plan)
    out = ["### Tasks by a horizon", "",
           "Tasks completed from the start to each simulated time (mean over seeds), as the "
           "League of Robot Runners reports throughput.", "",
           "| cell | " + " | ".join(f"{h:g} s" for h in hs) + " |", "|---|" + "---|" * len(hs)]
    for s in sorted(plain, key=lambda s: (s["size"], list(VARIANTS).index(s["variant"]))):
        out.append(f"| {s['label']} | " + " | ".join(
            "-" if s["horizons"].get(f"{h:g}") is None else f"{s['horizons'][f'{h:g}']:.1f}"
            for h in hs) + " |")
    return out + [""]


def _fault_section(plan: Plan, summaries: list[dict], figures: dict,
                   stats: list[dict], records: list[dict] = ()) -> list[str]:
    if not plan.faults:
        return []
    placed = {}  # label -> [(seed, the concrete spec)] of runs whose victim was placed
    for r in records:
        if r.get("fault_resolved"):
            placed.setdefault(r["label"], []).append((r["seed"], r["fault_resolved"]))
    lines = ["## Faults", "",
             f"At {plan.fault_size} robots. Tasks lost: tasks the no-fault run of the same "
             "seed completed after the fault minus the faulted run's. Back within 10 %: from "
             f"the fault to the first {WINDOW_S:g} s window from which every window reaches "
             "90 % of the no-fault run's mean rate after the fault.", ""]
    for k, spec in enumerate(plan.faults, start=1):
        lines += [f"### `--faults {spec}`", ""]
        if not any(s.get("fault_effects") for s in summaries if s["fault"] == spec):
            lines += ["No pair of a faulted run and its no-fault run yet.", ""]
        for s in summaries:
            if s["fault"] != spec:
                continue
            eff = s.get("fault_effects") or []
            if not eff:
                continue
            lost = t_interval([e["tasks_lost"] for e in eff])
            rec = ", ".join("never" if e["recovery_s"] is None else f"{e['recovery_s']:g} s"
                            for e in eff)
            lines.append(f"- {s['variant']}: tasks lost "
                         f"{_fmt({'mean': lost[0], 'ci95': lost[1]}, 1)} ({len(eff)} seeds); "
                         f"back within 10 % after: {rec}")
            if placed.get(s["label"]):
                lines.append("  (the victims, placed from the no-fault run: " + "; ".join(
                    f"seed {seed} `{spec}`" for seed, spec in sorted(placed[s["label"]])) + ")")
            noticed = detections(s["label"], records)
            if noticed:
                lines.append("  the coordinator noticed the victim (its `coordinator_lapses`, "
                             "after the fault): " + "; ".join(
                                 f"seed {seed} {text}" for seed, text in noticed))
        if f"fault_{k}" in figures:
            lines += ["", f"![fault {k}]({figures[f'fault_{k}']})"]
        if f"fault_lost_{k}" in figures:
            lines += ["", f"![tasks lost {k}]({figures[f'fault_lost_{k}']})"]
        for r in stats:
            if r["role"] == "fault" and r["what"] == spec and r.get("p_equiv") is not None:
                verdict = ("within it (equivalent)" if r["equivalent"]
                           else "not shown within it")
                lines.append(f"- {r['a'].rsplit('-n', 1)[0]}: the tasks lost after the fault "
                             f"against a margin of ± {r['margin']:.1f} tasks "
                             f"({100 * EQUIVALENCE_MARGIN:g} % of the no-fault run's): "
                             f"{verdict}, TOST p = {_p(r['p_equiv'])}")
        lines += [""]
    return lines + _stats_table(
        stats, "fault", "Paired tests of the faults (A: without the fault, or the first mode's "
        "tasks lost; B: with it, or the second mode's)", None)


def detections(label: str, records: list[dict]) -> list[tuple[int, str]]:
    """How long the coordinator took to notice each killed robot of a faulted cell's runs.

    For every run of ``label`` (a centralized fault cell) whose record keeps
    ``coordinator_lapses`` (``metrics.json``): per ``kill-robot`` victim of its fault (the placed
    one where ``fault_resolved`` says so), the first lapse of that robot at or after the kill,
    as ``"<robot>: <s> s (<reason>)"`` [s simulated after the kill], or ``"<robot>: not within
    the run"`` (a robot that held no workstation, or whose lease had not run out by the end).

    Returns:
        ``(seed, text)`` in order of seed; empty for decentralized cells and records without
        the key.
    """
    from swarm_common.faults import KILL_ROBOT, parse_faults

    out = []
    for r in sorted((r for r in records if r.get("label") == label
                     and r.get("exit_code") == EXIT_OK), key=lambda r: r["seed"]):
        lapses = (r.get("metrics") or {}).get("coordinator_lapses")
        spec = r.get("fault_resolved") or r.get("fault")
        if lapses is None or not spec:
            continue
        robots = tuple(f"Srobot{i}" for i in range(1, int(r["size"]) + 1))
        try:
            faults = parse_faults(spec, robots)
        except InputError:
            continue
        texts = []
        for f in (f for f in faults if f.kind == KILL_ROBOT):
            hit = next((e for e in lapses if e.get("robot") == f.robot
                        and float(e.get("t_s", -1.0)) >= f.at), None)
            texts.append(f"{f.robot}: not within the run" if hit is None else
                         f"{f.robot}: {float(hit['t_s']) - f.at:.1f} s ({hit.get('reason')})")
        if texts:
            out.append((int(r["seed"]), ", ".join(texts)))
    return out


def _fault_effects(plan: Plan, summaries: list[dict], figs: dict) -> dict[int, dict]:
    """Per fault spec k: the curves (mean tasks per window) and, per faulted cell, the
    per-seed effects (stored into the summaries as ``fault_effects``)."""
    out = {}
    for k, (spec, fault_s) in enumerate(zip(plan.faults, plan.fault_times, strict=True),
                                        start=1):
        curves, cumulative = {}, {}
        for s in summaries:
            if s["fault"] != spec:
                continue
            base_label = f"{s['variant']}-n{plan.fault_size}"
            base, hit = figs.get(base_label, {}), figs.get(s["label"], {})
            seeds = sorted(set(base) & set(hit))
            s["fault_effects"] = [fault_effect(base[x]["task_times"], hit[x]["task_times"],
                                               fault_s, plan.duration_s) for x in seeds]
            lost = [cumulative_lost(base[x]["task_times"], hit[x]["task_times"], fault_s,
                                    plan.duration_s) for x in seeds]
            if lost:
                cumulative[s["variant"]] = [t_interval(list(c)) for c in zip(*lost, strict=True)]
            for name, runs in ((f"{s['variant']}, no fault", base),
                               (f"{s['variant']}, fault", hit)):
                counts = [window_counts(f["task_times"], plan.duration_s)
                          for f in runs.values()]
                if counts:
                    curves[name] = (s["variant"], [sum(c) / len(counts)
                                                   for c in zip(*counts, strict=True)])
        out[k] = {"curves": curves, "fault_s": fault_s, "spec": spec, "cumulative": cumulative}
    return out


def _rounded(obj):
    """Computed figures to 9 significant digits: the same bytes from the same records across
    numpy and scipy releases that differ in the last bits."""
    if isinstance(obj, float):
        return float(f"{obj:.9g}")
    if isinstance(obj, dict):
        return {k: _rounded(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_rounded(v) for v in obj]
    return obj


def write_report(dirs: list[Path], out: Path) -> dict:
    """Merge the records of ``dirs`` and write ``experiment.json``, ``report.md`` and the
    figures into ``out``.

    Returns:
        ``report`` (its path), ``records`` (runs merged), ``missing`` (runs of the plan not
        among them).

    Raises:
        InputError: see :func:`load_dirs`.
    """
    plan, settings, records = load_dirs([Path(d) for d in dirs])
    rechecks = load_rechecks([Path(d) for d in dirs])
    checks = recheck_table(records, rechecks)
    figs = cell_figures(plan, records)
    summaries = summarize(plan, records, figs)
    stats = comparisons(plan, figs)
    faults = _fault_effects(plan, summaries, figs)
    out.mkdir(parents=True, exist_ok=True)
    figures: dict[str, str] = {}
    if summaries:
        label = {k: lab for k, lab, _ in MEASURES}
        for key in ("throughput", "ttt_mean", "holding_per_robot", "comm_bytes", "rtf",
                    "cpu_per_robot_ms"):
            figures[key] = plot_against_size(out, key, plan, summaries, figs, key, label[key])
        figures["tasks_over_time"] = plot_tasks_over_time(out, plan, summaries, figs)
        figures["time_to_task_ecdf"] = plot_ecdf(out, plan, summaries, figs)
        figures["tasks_per_robot"] = plot_tasks_per_robot(out, plan, summaries, figs)
        if plan.service_times:
            rows = service_rows(plan, summaries, records)
            if rows:
                figures["service_time"] = plot_service(out, plan, rows, figs)
        for size in plan.sizes:
            for key, fn in (("standstill_map", plot_standstill_map),
                            ("standing_over_time", plot_standing_over_time)):
                name = fn(out, plan, summaries, figs, size)
                if name:
                    figures[f"{key}_n{size}"] = name
        for k, f in faults.items():
            if f["curves"]:
                figures[f"fault_{k}"] = plot_fault(
                    out, f"fault_{k}", f["curves"], f["fault_s"],
                    f"tasks per {WINDOW_S:g} s, {plan.fault_size} robots, faults: {f['spec']}")
            if f["cumulative"]:
                figures[f"fault_lost_{k}"] = plot_cumulative_lost(
                    out, f"fault_lost_{k}", f["cumulative"], f["fault_s"],
                    f"tasks lost, {plan.fault_size} robots, faults: {f['spec']}: mean ± 95 %")
    text = build_report(plan, settings, records, summaries, stats, figures, checks) \
        if summaries else f"# {PROG}: no runs yet\n"
    (out / "report.md").write_text(text)
    doc = {"experiment": PROG, "settings": settings, "records": records,
           "summary": _rounded(summaries), "statistics": _rounded(stats), "figures": figures,
           **({"rechecks": rechecks, "recheck_table": checks} if rechecks else {})}
    (out / "experiment.json").write_text(json.dumps(doc, indent=1, sort_keys=True,
                                                    default=str) + "\n")
    return {"report": out / "report.md", "records": len(records),
            "missing": len(plan.runs_in_order()) - len(records)}

