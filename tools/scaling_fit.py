"""Fit the scaling model of docs/design/scaling.md to measured runs, check it, predict.

The model (per simulated second; N robots, H hosts of C cores, G group processes)::

    T = s·N + max_h (g·N_h + [h = 0]·o·N) / C + b·N / G + a + w·(N − N_0) / L,   RTF = 1 / T

s, g, o [s of CPU per robot per simulated s] are a run's own (``tools/cpu_by_role.py``: the
simulator, the group processes, swarm-up); a [s] and b [s per robot of a group] are fitted by
least squares (numpy.linalg.lstsq) to the one-host runs given with ``--fit``; w [bytes per remote
robot per simulated s] and L [bytes/s] price rank 0's link. Runs given with ``--check`` are
predicted from the fit (with their own s, g, o when they have a cpu_by_role JSON, else those of
the one-host run of the same size) and set beside their measured RTF (``rtf_from_ready`` where a
JSON has it, else ``rtf``); network namespaces on one
machine share its cores (C is then the machine's, and the link term is left out).

Usage::

    python tools/scaling_fit.py --fit one_20.json one_50.json one_100.json one_200.json \
        [--check one_1000.json ns2_100.json ...] [--cores 2] [--json OUT]
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

GROUPS_PER_HOST = 2  # swarm-up's default layout on this machine: K = its cores


def load(path: Path) -> dict:
    """A cpu_by_role JSON (``cpu_ms_per_robot_per_sim_s``) or a host_traffic JSON
    (``robots_per_host``)."""
    d = json.loads(path.read_text())
    d["_path"] = str(path)
    return d


def costs(run: dict) -> tuple[float, float, float]:
    """(s, g, o) [s of CPU per robot per simulated s] of a cpu_by_role run."""
    c = run["cpu_ms_per_robot_per_sim_s"]
    return c.get("sim", 0.0) / 1e3, c.get("group", 0.0) / 1e3, c.get("swarm-up", 0.0) / 1e3


def fit(runs: list[dict], cores: int) -> tuple[float, float]:
    """(a, b) by least squares: T − s·N − (g + o)·N/C = a + b·N/G on one host."""
    rows, rhs = [], []
    for r in runs:
        n = r["robots"]
        s, g, o = costs(r)
        rows.append([1.0, n / GROUPS_PER_HOST])
        rhs.append(1.0 / r["rtf"] - s * n - (g + o) * n / cores)
    (a, b), *_ = np.linalg.lstsq(np.array(rows), np.array(rhs), rcond=None)
    return float(a), float(b)


def predict(n: int, per_host: list[int], cores_per_host: float, groups: int, s: float, g: float,
            o: float, a: float, b: float, w: float = 0.0, link: float = 125e6,
            shared_cores: bool = False) -> tuple[float, dict]:
    """Predicted T [s per simulated s] and its terms. ``shared_cores``: the hosts are namespaces
    on one machine of ``cores_per_host`` cores (their navigators add up on them, no link)."""
    if shared_cores:
        hosts_term = (g * n + o * n) / cores_per_host
        link_term = 0.0
    else:
        hosts_term = max((g * nh + (o * n if h == 0 else 0.0)) / cores_per_host
                         for h, nh in enumerate(per_host))
        link_term = w * (n - per_host[0]) / link
    terms = {"simulator": s * n, "hosts": hosts_term, "spread": b * n / groups, "hand-overs": a,
             "link": link_term}
    return sum(terms.values()), terms


def main() -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--fit", type=Path, nargs="+", required=True, help="one-host cpu_by_role JSONs")
    p.add_argument("--check", type=Path, nargs="*", default=[],
                   help="more runs to predict (cpu_by_role or host_traffic JSONs)")
    p.add_argument("--cores", type=int, default=2, help="this machine's cores")
    p.add_argument("--json", type=Path, default=None)
    a = p.parse_args()
    for path in [*a.fit, *a.check]:
        if not path.is_file():
            print(f"scaling_fit: {path}: no such file", file=sys.stderr)
            return 2
    one = [load(x) for x in a.fit]
    ca, cb = fit(one, a.cores)
    by_size = {r["robots"]: r for r in one}
    print(f"fit over {len(one)} one-host runs: a = {ca * 1e3:.2f} ms, b = {cb * 1e3:.3f} ms per "
          "robot of a group")
    rows = []
    print(f"{'run':52s} {'N':>5s} {'s':>6s} {'g':>6s} {'o':>6s} {'pred':>7s} {'meas':>7s} "
          f"{'err':>6s}")
    for path in [*a.fit, *a.check]:
        r = load(path)
        if "robots_per_host" in r:  # host_traffic: namespaces on this machine
            per_host = r["robots_per_host"]
            n = sum(per_host)
            base = by_size.get(n)
            if base is None:
                print(f"{path}: no one-host run of {n} robots for its costs", file=sys.stderr)
                continue
            s, g, o = costs(base)
            groups = GROUPS_PER_HOST * len(per_host)
            t, terms = predict(n, per_host, a.cores, groups, s, g, o, ca, cb, shared_cores=True)
        else:
            n = r["robots"]
            s, g, o = costs(r)
            t, terms = predict(n, [n], a.cores, GROUPS_PER_HOST, s, g, o, ca, cb)
        pred, meas = 1.0 / t, r.get("rtf_from_ready", r["rtf"])
        err = pred / meas - 1.0
        label = Path(r["_path"]).name
        print(f"{label:52s} {n:5d} {s * 1e3:6.2f} {g * 1e3:6.2f} {o * 1e3:6.2f} {pred:7.3f} "
              f"{meas:7.3f} {err:+6.0%}")
        rows.append({"run": label, "robots": n, "s_ms": s * 1e3, "g_ms": g * 1e3,
                     "o_ms": o * 1e3, "predicted_rtf": pred, "measured_rtf": meas,
                     "error": err, "terms_s": terms})
    if a.json:
        a.json.write_text(json.dumps({"a_s": ca, "b_s": cb, "cores": a.cores, "runs": rows},
                                     indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
