"""The behaviour rule of a navigator change, from two sets of swarm-experiment records.

A change that alters the simulated run on purpose must keep the thesis's figures over the
protocol's seeds (docs/guides/coordination.md#the-comparison-swarm-experiment): 0 collisions, 0
aborted goals, throughput after the warm-up not lower (paired over the seeds), no more robots
that complete no task. This reads the records of one variant before and after the change
(``swarm-experiment --variants decentralized --no-ablations --no-faults``, each at its commit)
and prints, per swarm size, the figures of both and the paired comparison
(:func:`swarm_bench.experiment_stats.paired`; one-sided p of "after is lower" from the paired
t statistic). Exit 0 when every rule holds, 1 when one does not, 2 on bad input.

Usage::

    python tools/behaviour_check.py BEFORE_DIR AFTER_DIR [--variant decentralized]
        [--warmup 300] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from swarm_bench.experiment_stats import paired, run_figures  # noqa: E402


def load(directory: Path, variant: str, warmup_s: float) -> dict[int, dict[int, dict]]:
    """size -> seed -> (run_figures, record) of ``variant``'s main runs in ``directory``."""
    out: dict[int, dict[int, dict]] = {}
    for path in sorted((directory / "records").glob(f"{variant}-n*-s*.json")):
        record = json.loads(path.read_text())
        if record.get("variant") != variant or record.get("role") != "main":
            continue
        figs = run_figures(record, warmup_s)
        if figs is not None:
            figs["aborted"] = record["metrics"].get("goals_aborted", 0)
            figs["commit"] = record.get("commit", "")[:7]
            out.setdefault(int(record["size"]), {})[int(record["seed"])] = figs
    return out


def check(before: dict, after: dict) -> tuple[list[dict], bool]:
    """Per size both have: the figures and the rules; and whether every rule holds."""
    from scipy import stats

    rows, ok = [], True
    for size in sorted(set(before) & set(after)):
        b, a = before[size], after[size]
        seeds = sorted(set(a) & set(b))
        thr = paired({s: a[s]["throughput"] for s in seeds},
                     {s: b[s]["throughput"] for s in seeds})
        diffs = thr["diffs"]
        p_lower = None
        if len(diffs) >= 2 and any(d != diffs[0] for d in diffs):
            res = stats.ttest_1samp(diffs, 0.0, alternative="less")
            p_lower = float(res.pvalue)
        collisions = sum(int(a[s]["collisions"]) for s in seeds)
        aborted = sum(int(a[s]["aborted"]) for s in seeds)
        idle_b = sum(int(b[s]["idle_robots"]) for s in seeds)
        idle_a = sum(int(a[s]["idle_robots"]) for s in seeds)
        rules = {"0 collisions": collisions == 0, "0 aborted goals": aborted == 0,
                 "throughput not lower (paired t, one-sided p >= 0.05)":
                     p_lower is None or p_lower >= 0.05 or (thr["diff"] or 0) >= 0,
                 "robots without a task not more": idle_a <= idle_b}
        ok = ok and all(rules.values()) and len(seeds) > 0
        rows.append({"size": size, "seeds": seeds,
                     "commits": sorted({b[s]["commit"] for s in seeds}
                                       | {a[s]["commit"] for s in seeds}),
                     "throughput_before": [b[s]["throughput"] for s in seeds],
                     "throughput_after": [a[s]["throughput"] for s in seeds],
                     "paired": thr, "p_lower_one_sided": p_lower,
                     "collisions_after": collisions, "aborted_after": aborted,
                     "idle_robots_before": idle_b, "idle_robots_after": idle_a,
                     "cpu_ms_before": [b[s]["cpu_per_robot_ms"] for s in seeds],
                     "cpu_ms_after": [a[s]["cpu_per_robot_ms"] for s in seeds],
                     "rules": rules})
    return rows, ok


def _mean(values) -> float:
    vals = [float(v) for v in values if v is not None and math.isfinite(float(v))]
    return sum(vals) / len(vals) if vals else math.nan


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("before", type=Path)
    p.add_argument("after", type=Path)
    p.add_argument("--variant", default="decentralized")
    p.add_argument("--warmup", type=float, default=300.0, help="[s] simulated warm-up")
    p.add_argument("--json", type=Path, default=None)
    a = p.parse_args()
    for d in (a.before, a.after):
        if not (d / "records").is_dir():
            print(f"behaviour_check: {d}: no records/ directory", file=sys.stderr)
            return 2
    rows, ok = check(load(a.before, a.variant, a.warmup), load(a.after, a.variant, a.warmup))
    if not rows:
        print(f"behaviour_check: no size with {a.variant} records in both", file=sys.stderr)
        return 2
    for r in rows:
        t = r["paired"]
        print(f"{r['size']} robots, seeds {r['seeds']} (commits {', '.join(r['commits'])}):")
        print(f"  throughput [tasks/h] before {_mean(r['throughput_before']):.1f}, after "
              f"{_mean(r['throughput_after']):.1f}; after - before {t['diff']:+.1f} "
              f"(95 % CI +-{t['ci95'] or 0:.1f}, paired t p = {t['p_t']}, one-sided p(lower) "
              f"= {r['p_lower_one_sided']})")
        print(f"  robots without a task before {r['idle_robots_before']}, after "
              f"{r['idle_robots_after']}; collisions after {r['collisions_after']}, aborted "
              f"goals after {r['aborted_after']}")
        print(f"  CPU per robot [ms per simulated s] before {_mean(r['cpu_ms_before']):.2f}, "
              f"after {_mean(r['cpu_ms_after']):.2f}")
        for rule, held in r["rules"].items():
            print(f"  {'ok  ' if held else 'FAIL'} {rule}")
    if a.json:
        a.json.write_text(json.dumps({"variant": a.variant, "warmup_s": a.warmup,
                                      "sizes": rows, "ok": ok}, indent=1))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
