"""Fairness of a committed comparison: Jain's index of tasks per robot, and robots without a task.

Reads a ``swarm-experiment`` JSON (``docs/experiments/<world>/experiment.json``) and prints, for
every size with both main variants, each one's Jain's index over seeds (mean ± 95 % interval,
Student's t), the paired t-test between them (not Holm-adjusted: the report's family does not
hold it yet), and the robots that completed no task, per seed. Tasks per robot are the runs'
``robot_tasks`` (the whole run, warm-up included).

Jain's index (Jain, Chiu and Hawe 1984): ``(sum x)^2 / (n * sum x^2)`` over the n robots' task
counts x; 1 when every robot completed as many tasks, 1/n when one robot completed them all.

    python tools/fairness.py docs/experiments/slim_blockage/experiment.json
"""

from __future__ import annotations

import json
import math
import statistics
import sys
from pathlib import Path

MAIN = ("decentralized", "centralized-scheduler")


def jain(counts: list[int]) -> float | None:
    """Jain's index of ``counts`` (None when no robot completed a task)."""
    total = sum(counts)
    return total * total / (len(counts) * sum(c * c for c in counts)) if total else None


def interval(values: list[float]) -> tuple[float, float]:
    """Mean and half-width of the 95 % Student's t interval."""
    from scipy import stats

    half = stats.t.ppf(0.975, len(values) - 1) * statistics.stdev(values) / math.sqrt(
        len(values))
    return statistics.mean(values), half


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        print("fairness: usage: python tools/fairness.py EXPERIMENT.json", file=sys.stderr)
        return 2
    if not Path(argv[0]).is_file():
        print(f"fairness: EXPERIMENT.json: no such file '{argv[0]}'", file=sys.stderr)
        return 2
    from scipy import stats

    doc = json.loads(Path(argv[0]).read_text())
    cells: dict[tuple[str, int], dict[int, tuple[float, int]]] = {}
    for rec in doc["records"]:
        if rec["fault"] or rec["variant"] not in MAIN:
            continue
        counts = [int(c) for c in rec["metrics"]["robot_tasks"]]  # one per robot
        cells.setdefault((rec["variant"], rec["size"]), {})[rec["seed"]] = (
            jain(counts), sum(1 for c in counts if c == 0))
    print("| robots | Jain's index, decentralized | centralized scheduler | p (paired t) | "
          "robots without a task, per seed (dec / cen) |")
    print("|---|---|---|---|---|")
    for size in sorted({n for _, n in cells}):
        dec, cen = cells.get((MAIN[0], size), {}), cells.get((MAIN[1], size), {})
        seeds = sorted(set(dec) & set(cen))
        if len(seeds) < 2:
            continue
        a, b = [dec[s][0] for s in seeds], [cen[s][0] for s in seeds]
        (ma, ha), (mb, hb) = interval(a), interval(b)
        p = stats.ttest_rel(a, b).pvalue
        zero = (", ".join(str(dec[s][1]) for s in seeds) + " / "
                + ", ".join(str(cen[s][1]) for s in seeds))
        print(f"| {size} | {ma:.2f} ± {ha:.2f} | {mb:.2f} ± {hb:.2f} | {p:.4f} | {zero} |")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
