"""``swarm-experiment table DIR [DIR ...]``: the headline table across experiments.

One row per arm, world, swarm size and workstation service time, read from the committed
reports' ``experiment.json`` alone (the summaries and the paired statistics that
:func:`swarm_bench.experiment_report.write_report` wrote; nothing is recomputed, so the table
says what the reports say): throughput after the warm-up [tasks/h], Jain's index of the tasks per
robot and the robots that completed no task, each as mean ± half-width of the 95 % interval
across seeds (Student's t), and, for every arm but the reference (``decentralized``), its paired
difference from the reference (reference − arm, the reports' ``A − B``) with the paired t-test's
p after Holm's correction over the comparisons of its own report.

Fault cells, ablations and factorial cells are left out: the table compares the main arms, at
their sizes (the main cells, the world's own service time) and at the service-time cells.
"""

from __future__ import annotations

import json
from pathlib import Path

from swarm_bench.experiment_plan import VARIANTS, plan_from_settings
from swarm_bench.experiment_report import _fmt, _p, own_service_time
from swarm_common.errors import InputError

REFERENCE = "decentralized"
"""The arm every other arm is compared with (the reports' ``A``)."""
MEASURES = (("throughput", "throughput [tasks/h]", 0), ("jain", "Jain's index", 3),
            ("idle_robots", "robots without a task", 1))
"""(summary key, column title, decimals) of the table's measures."""


def rows_of(path: Path) -> list[dict]:
    """The table's rows of one report directory (its ``experiment.json``).

    Returns:
        dicts with ``report`` (the directory's name), ``world``, ``size``, ``service_s``,
        ``variant``, ``seeds`` (runs ended well), ``commits`` (of the runs) and, per measure
        key, ``<key>`` (the summary's mean and ci95) and ``<key>_vs`` (the paired comparison
        with the reference, or None).

    Raises:
        InputError: ``path`` holds no ``experiment.json`` or it is not a report.
    """
    doc_path = path / "experiment.json"
    if not doc_path.is_file():
        raise InputError(f"DIR: '{path}' holds no experiment.json (write it with "
                         "'swarm-experiment report DIR')")
    try:
        doc = json.loads(doc_path.read_text())
        plan = plan_from_settings(doc["settings"])
        summaries, stats = doc["summary"], doc["statistics"]
    except (ValueError, KeyError, TypeError) as exc:
        raise InputError(f"DIR: '{doc_path}' is not an experiment report ({exc})") from None
    own = own_service_time(plan, doc.get("records", []))
    world = Path(str(plan.world)).stem if "/" in str(plan.world) else str(plan.world)
    variant = {s["label"]: s["variant"] for s in summaries}
    pairs = {(s["b"], s["measure"]): s for s in stats
             if s.get("role") in ("main", "service") and variant.get(s.get("a")) == REFERENCE}
    commits = {}
    for r in doc.get("records", []):
        commits.setdefault(r.get("label"), set()).add(str(r.get("commit") or "?")[:7])
    out = []
    for s in summaries:
        if s.get("fault") or s.get("role") not in ("main", "service") or not s.get("runs_ok"):
            continue
        row = {"report": path.name, "world": world, "size": s["size"],
               "service_s": float(s.get("service_s", own)), "variant": s["variant"],
               "seeds": s["runs_ok"], "commits": sorted(commits.get(s["label"], ()))}
        for key, _, _ in MEASURES:
            row[key] = s.get(key)
            row[key + "_vs"] = pairs.get((s["label"], key))
        out.append(row)
    return out


def headline(dirs: list[Path]) -> str:
    """The Markdown table of every row of ``dirs`` (:func:`rows_of`), sorted by world, size,
    service time, report and arm (in :data:`~swarm_bench.experiment_plan.VARIANTS`' order, the
    reference first), with a note on how to read it.

    Raises:
        InputError: see :func:`rows_of`.
    """
    rows = [r for d in dirs for r in rows_of(Path(d))]
    order = {v: k for k, v in enumerate(VARIANTS)}  # decentralized first
    rows.sort(key=lambda r: (r["world"], r["size"], r["service_s"], r["report"],
                             order.get(r["variant"], len(order)), r["variant"]))
    head = ["world", "robots", "service [s]", "arm", "seeds"]
    for _, title, _ in MEASURES:
        head += [title, "Δ, p (Holm)"]
    head.append("report")
    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in rows:
        cells = [r["world"], str(r["size"]), f"{r['service_s']:g}", r["variant"],
                 str(r["seeds"])]
        for key, _, digits in MEASURES:
            cells.append(_fmt(r[key], digits))
            vs = r[key + "_vs"]
            cells.append("-" if vs is None else
                         f"{_fmt({'mean': vs['diff'], 'ci95': vs['ci95']}, digits)}, "
                         f"{_p(vs['p_holm'])} ({vs['n']})")
        cells.append(r["report"])
        lines.append("| " + " | ".join(cells) + " |")
    commits = sorted({c for r in rows for c in r["commits"]})
    note = (f"Mean ± 95 % interval across seeds; Δ: {REFERENCE} − arm per seed, paired (mean ± "
            "95 % interval), p: the paired t-test after Holm's correction within its report, "
            "(n): seeds paired. Runs from commit(s) " + (", ".join(commits) or "-") + "; read "
            "from " + ", ".join(str(Path(d) / "experiment.json") for d in dirs) + ".")
    return "\n".join(lines) + "\n\n" + note + "\n"
