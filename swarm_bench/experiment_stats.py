"""The arithmetic of ``swarm-experiment``: a run's figures, intervals, paired tests, Holm.

Pure (numpy/scipy, no ROS, no plotting). The conventions are the protocol's
(``shared/reference/experiment_protocol.md``): Student's t intervals across seeds; per pair of
variants, the per-seed differences with their interval and a paired test; Holm's step-down
correction across the claims made.

Why the paired t-test is the primary test, and Wilcoxon's signed-rank test only a check: with
five seeds the signed-rank test's smallest possible two-sided p is 2/2^5 = 0.0625, so it can
never reject at 0.05, whatever the data; the t-test can, and its assumption (differences
roughly normal) is the one to doubt, so both are reported.
"""

from __future__ import annotations

import math

from swarm_common.errors import EXIT_OK

WINDOW_S = 30.0  # [s] simulated: fault-curve window


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


def jain(counts: list[int]) -> float | None:
    """Jain's fairness index of ``counts`` (Jain, Chiu and Hawe 1984): ``(sum x)^2 / (n * sum
    x^2)`` over the n robots' task counts x; 1 when every robot completed as many tasks, 1/n when
    one robot completed them all; None when no robot completed a task."""
    total = sum(counts)
    return total * total / (len(counts) * sum(c * c for c in counts)) if total else None


def task_intervals(robot_task_times: list[list[float]], sim_time_s: float,
                   warmup_s: float) -> tuple[list[float], list[float]]:
    """Each robot's tasks as intervals from one completion to its next (its first from the
    run's start), both modes alike, and the task each robot still had open at the end.

    Counted are the intervals that end after the warm-up, wherever they began (a robot that
    completes nothing after it still counts, with its one open interval).

    Args:
        robot_task_times: per robot, the simulated times [s] its tasks were completed.
        sim_time_s: [s] the run's end; warmup_s: [s] the warm-up.

    Returns:
        ``(completed, still_open)``: durations [s] of the completed tasks, and the ages [s] at
        the end of the open ones (right-censored observations).
    """
    completed, still_open = [], []
    for times in robot_task_times:
        start = 0.0
        for t in sorted(float(v) for v in times):
            if t > warmup_s:
                completed.append(t - start)
            start = t
        if sim_time_s > start and sim_time_s > warmup_s:
            still_open.append(sim_time_s - start)
    return completed, still_open


def km_quantiles(completed: list[float], still_open: list[float],
                 levels: tuple[float, ...] = (0.5, 0.95)) -> list[float | None]:
    """Quantiles of the time to task with the open tasks counted as right-censored: the
    Kaplan-Meier estimate (``scipy.stats.ecdf`` of ``CensoredData``; Kaplan and Meier 1958),
    the smallest time whose estimated share of tasks done is at least the level; None where the
    estimate never reaches it (too many tasks still open) or nothing completed."""
    if not completed:
        return [None] * len(levels)
    from scipy.stats import CensoredData, ecdf

    cdf = ecdf(CensoredData(uncensored=completed, right=still_open)).cdf
    out = []
    for level in levels:
        hit = [q for q, p in zip(cdf.quantiles, cdf.probabilities, strict=True)
               if p >= level - 1e-12]
        out.append(float(hit[0]) if hit else None)
    return out


def run_figures(record: dict, warmup_s: float) -> dict | None:
    """The protocol's figures of one swarm-up run (None if it did not end well).

    Args:
        record: a :func:`swarm_bench.bench.run_swarm_up` record.
        warmup_s: [s] simulated time left out of the throughput.

    Returns:
        ``throughput`` [tasks/h after the warm-up], ``ttt_mean``/``ttt_p95`` [s],
        ``holding_per_robot`` [s], ``jain`` (:func:`jain` of the tasks per robot, the whole
        run), ``idle_robots`` (robots that completed no task) and
        ``min_tasks`` (the fewest tasks of a robot), ``collisions``, ``late_ticks``,
        ``cpu_per_robot_ms``
        [ms per simulated s], ``comm_msgs``/``comm_bytes`` [per simulated s, total],
        ``coord_msgs``/``coord_bytes`` (without the map), ``comm_bytes_per_robot``, ``rtf``,
        ``tasks``, ``reproducible``, ``reservation_conflicts``, ``task_times`` and
        ``task_durations`` [s] (per task, in completion order), ``robot_tasks`` (tasks of each
        robot), ``distance_per_task`` [m] (all robots' distance driven over the tasks
        completed; None for records without the robots' distances), ``ttt_km_median`` and
        ``ttt_km_p95`` [s] (:func:`km_quantiles` of :func:`task_intervals`; None for records
        without each robot's task times), ``waiting_per_task`` [s] (the metrics'
        ``waiting_per_task_s``: time without progress toward the task's workstation, from
        ground truth, the same in every mode; None for records without it), ``censored_ttt``
        (whether the record has both: each robot's task times and the waiting per task),
        ``standstills`` (the simulator's episodes of >= 60 s), ``min_separation`` [m],
        ``sim_time``, ``robots``.
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
    dist = m.get("robot_distance_m")
    tasks = m.get("tasks_completed")
    per_task = (sum(dist) / tasks if dist and tasks and all(d is not None for d in dist)
                else None)
    robot_times = m.get("robot_task_times")
    km = (km_quantiles(*task_intervals(robot_times, sim, warmup_s)) if robot_times
          else [None, None])
    return {
        "throughput": thr,
        "ttt_mean": m.get("time_to_task_mean_s"),
        "ttt_p95": m.get("time_to_task_p95_s"),
        "holding_per_robot": holding / n,
        "jain": jain([int(v) for v in m.get("robot_tasks") or []]),
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
        "distance_per_task": per_task,
        "waiting_per_task": m.get("waiting_per_task_s"),
        "ttt_km_median": km[0],
        "ttt_km_p95": km[1],
        "censored_ttt": bool(robot_times) and m.get("waiting_per_task_s") is not None,
        "rtf": m.get("rtf"),
        "tasks": m.get("tasks_completed"),
        "reproducible": m.get("reproducible"),
        "reservation_conflicts": m.get("reservation_conflicts"),
        "task_times": times,
        "task_durations": [float(d) for d in m.get("task_durations_s") or []],
        "robot_tasks": [int(v) for v in m.get("robot_tasks") or []],
        "standstills": [e for e in m.get("standstills") or [] if isinstance(e, dict)],
        "min_separation": m.get("min_separation_m"),
        "sim_time": sim,
        "robots": n,
    }


MEASURES = (
    ("throughput", "throughput after warm-up [tasks/h]", 1),
    ("ttt_mean", "time to task, mean [s]", 1),
    ("ttt_p95", "time to task, 95th percentile [s]", 1),
    ("ttt_km_median", "time to task after warm-up, open tasks counted: median [s]", 1),
    ("ttt_km_p95", "time to task after warm-up, open tasks counted: 95th percentile [s]", 1),
    ("holding_per_robot", "holding + waiting per robot [s]", 1),
    ("jain", "Jain's index of tasks per robot", 3),
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
    ("distance_per_task", "distance driven per task [m]", 1),
    ("waiting_per_task", "waiting per task: no progress toward its workstation [s]", 1),
    ("rtf", "real-time factor", 2),
)


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


def paired(a: dict[int, float], b: dict[int, float], level: float = 0.95) -> dict:
    """The paired comparison of two variants over the seeds both have.

    Args:
        a, b: seed -> the measure of variant A, of variant B (None or non-finite: left out).
        level: the interval's confidence.

    Returns:
        ``n`` (seeds paired), ``diff`` (mean of A - B), ``ci95`` (its Student's-t half-width;
        None with n < 2), ``p_t`` (two-sided paired t-test; 1.0 when every difference is 0,
        0.0 when they are all equal and not 0; None with n < 2), ``p_wilcoxon`` (two-sided
        Wilcoxon signed-rank, exact for n <= 25 without ties; None with n < 2 or every
        difference 0), ``rel`` (mean of B over mean of A, minus 1: B's change against A;
        None if A's mean is 0), ``diffs`` (per seed, seed order).

    Source: scipy.stats.ttest_rel / scipy.stats.wilcoxon (zero_method "wilcox").
    """
    seeds = sorted(s for s in set(a) & set(b) if _finite(a[s]) and _finite(b[s]))
    diffs = [float(a[s]) - float(b[s]) for s in seeds]
    n = len(diffs)
    out = {"n": n, "diff": None, "ci95": None, "p_t": None, "p_wilcoxon": None, "rel": None,
           "diffs": diffs, "seeds": seeds}
    if not n:
        return out
    mean, half = t_interval(diffs, level)
    out["diff"], out["ci95"] = mean, half
    ma = sum(float(a[s]) for s in seeds) / n
    mb = sum(float(b[s]) for s in seeds) / n
    out["rel"] = (mb / ma - 1.0) if ma else None
    if n < 2:
        return out
    from scipy import stats

    if all(d == diffs[0] for d in diffs):
        out["p_t"] = 1.0 if diffs[0] == 0 else 0.0
    else:
        out["p_t"] = float(stats.ttest_rel([float(a[s]) for s in seeds],
                                           [float(b[s]) for s in seeds]).pvalue)
    if any(diffs):
        out["p_wilcoxon"] = float(stats.wilcoxon(diffs, zero_method="wilcox").pvalue)
    return out


EQUIVALENCE_MARGIN = 0.05
"""The share of the no-fault run's tasks after the fault within which a fault's cost counts
as none (the equivalence margin of :func:`equivalence`)."""


def equivalence(diffs: list[float], margin: float, level: float = 0.05) -> dict:
    """Two one-sided t-tests (TOST): is the mean difference within ``±margin``?

    Args:
        diffs: per-seed differences (no fault minus fault).
        margin: the margin (> 0), in the differences' unit.
        level: the tests' level.

    Returns:
        ``margin``, ``p_equiv`` (the larger of the two one-sided p-values; None with fewer than
        2 differences or a zero spread) and ``equivalent`` (``p_equiv < level``).

    Source: Schuirmann (1987), the two one-sided tests procedure; ``scipy.stats.ttest_1samp``.
    """
    out = {"margin": margin, "p_equiv": None, "equivalent": False}
    if len(diffs) < 2 or not margin > 0 or len(set(diffs)) < 2:
        return out
    from scipy import stats

    lower = stats.ttest_1samp(diffs, -margin, alternative="greater").pvalue
    upper = stats.ttest_1samp(diffs, margin, alternative="less").pvalue
    out["p_equiv"] = float(max(lower, upper))
    out["equivalent"] = out["p_equiv"] < level
    return out


def cumulative_lost(base: list[float], hit: list[float], fault_s: float, duration_s: float,
                    step_s: float = WINDOW_S) -> list[float]:
    """Tasks lost to a fault by each time after it: for t = fault + step, fault + 2 step, ...
    up to the run's end, the no-fault run's tasks completed in [fault, t) minus the faulted
    run's (same seed; :data:`WINDOW_S` steps)."""
    out = []
    t = fault_s + step_s
    while t <= duration_s + 1e-9:
        out.append(float(sum(1 for x in base if fault_s <= x < t)
                         - sum(1 for x in hit if fault_s <= x < t)))
        t += step_s
    return out


def factorial_2x2(y: dict[tuple[int, int], dict[int, float]]) -> dict[str, dict[int, float]]:
    """The effects of a 2 x 2 design, per seed.

    Args:
        y: (level of A, level of B), each 0 or 1 -> seed -> the measure.

    Returns:
        ``A``, ``B`` (main effects: level 1 minus level 0, averaged over the other factor's two
        levels) and ``AxB`` (the interaction: A's effect at B = 1 minus at B = 0), each seed ->
        value, over the seeds all four cells have. Test them with :func:`paired` against 0.

    Source: the effects of a 2^2 factorial design (Montgomery, *Design and Analysis of
    Experiments*, ch. 6), computed per seed so that the seeds pair them.
    """
    seeds = sorted(set.intersection(*(set(k for k, v in y[c].items() if _finite(v))
                                      for c in ((0, 0), (0, 1), (1, 0), (1, 1)))))
    a, b, ab = {}, {}, {}
    for s in seeds:
        y00, y01, y10, y11 = (float(y[c][s]) for c in ((0, 0), (0, 1), (1, 0), (1, 1)))
        a[s] = ((y10 - y00) + (y11 - y01)) / 2.0
        b[s] = ((y01 - y00) + (y11 - y10)) / 2.0
        ab[s] = (y11 - y01) - (y10 - y00)
    return {"A": a, "B": b, "AxB": ab}


def holm(pvalues: list[float | None]) -> list[float | None]:
    """Holm's step-down adjusted p-values (None stays None and does not count).

    The i-th smallest of m p-values becomes max over j <= i of (m - j + 1) p_(j), capped at 1;
    a claim is made where the adjusted p is below 0.05 (Holm 1979, "A simple sequentially
    rejective multiple test procedure").
    """
    idx = sorted((i for i, p in enumerate(pvalues) if p is not None), key=lambda i: pvalues[i])
    m = len(idx)
    out: list[float | None] = [None] * len(pvalues)
    running = 0.0
    for rank, i in enumerate(idx):
        running = max(running, min(1.0, (m - rank) * float(pvalues[i])))
        out[i] = running
    return out


def tasks_by(times: list[float], horizon_s: float) -> int:
    """Tasks completed by simulated time ``horizon_s`` (League of Robot Runners' horizons)."""
    return sum(1 for t in times if t <= horizon_s)


def littles_law(times: list[float], durations: list[float], robots: int, warmup_s: float,
                end_s: float) -> dict:
    """Little's law after the warm-up: robots busy N against throughput x mean time to task.

    Every robot always has a task, so N should be about lambda W, with lambda the tasks
    completed per simulated second after the warm-up and W their mean time to task. Tasks
    still open at the end are censored, so lambda W falls below N the more, the longer the
    tasks are against the window.

    Returns:
        ``lambda_w`` and ``ratio`` (lambda W / N), None without tasks.
    """
    sel = [d for t, d in zip(times, durations, strict=False) if t > warmup_s]
    if not sel or end_s <= warmup_s or not robots:
        return {"lambda_w": None, "ratio": None}
    lw = len(sel) / (end_s - warmup_s) * (sum(sel) / len(sel))
    return {"lambda_w": lw, "ratio": lw / robots}


def _finite(v) -> bool:
    return v is not None and isinstance(v, int | float) and math.isfinite(float(v))
