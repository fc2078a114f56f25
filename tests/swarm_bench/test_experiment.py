"""``swarm-experiment``: its arithmetic (Student's t, paired tests, Holm, windows, fault dips),
variants, flags, shards, resume, the report rebuilt from records, and a tiny real sweep."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from swarm_bench.experiment import (
    VARIANTS,
    build_parser,
    nav_params_file,
    plan_from_settings,
    record_path,
    validate,
    variant_args,
)
from swarm_bench.experiment_stats import (
    fault_effect,
    holm,
    littles_law,
    paired,
    run_figures,
    t_interval,
    window_counts,
)
from swarm_common.errors import InputError

SWARM_EXPERIMENT = Path(sys.executable).parent / "swarm-experiment"
TWO_ARMS = ("--variants", "decentralized,centralized-scheduler")
"""The first two main arms: the mechanics tests keep to them (their fake rates name them)."""
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(autouse=True)
def clean_tree(monkeypatch):
    """The code's repository as a clean commit, whatever the tree these tests run from (a test
    of the refusal makes it dirty)."""
    import swarm_bench.bench as bench

    state = {"commit": "0" * 40, "dirty": False, "diff_sha256": None}
    monkeypatch.setattr(bench, "git_commit", lambda: dict(state))
    return state


def test_a_dirty_tree_is_refused_unless_allowed_and_then_its_diff_is_recorded(
        clean_tree, tmp_path, monkeypatch, capsys):
    """Every run from a clean commit: a tracked file that differs from the commit refuses the
    sweep (exit 2, one line naming --allow-dirty, nothing written); --allow-dirty runs it and
    every record keeps the diff's SHA-256, which the report names."""
    import swarm_bench.bench as bench
    from swarm_bench import experiment

    clean_tree.update(dirty=True, diff_sha256="ab" * 32)
    out = tmp_path / "x"
    argv = ["--output", str(out), "--sizes", "20", "--runs", "1", "--no-faults",
            "--no-ablations"]
    assert experiment.main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--allow-dirty" in err[0] and "Traceback" not in err[0]
    assert not out.exists()
    monkeypatch.setattr(bench, "run_swarm_up", lambda bcfg, n, r, stop, view: {
        **fake_record("?", "?", bcfg.coordination, n, bcfg.seed, 2.0), "interrupted": False})
    assert experiment.main([*argv, "--allow-dirty"]) == 0
    records = [json.loads(p.read_text()) for p in sorted((out / "records").glob("*.json"))]
    assert records and all(r["dirty"] and r["diff_sha256"] == "ab" * 32 for r in records)
    assert f"{'0' * 40} (dirty, diff sha256 {'ab' * 6})" in (out / "report.md").read_text()


def test_t_interval_matches_the_student_t_table():
    mean, half = t_interval([10.0, 12.0, 14.0])
    # s = 2, n = 3, t(0.975, 2) = 4.3027: 4.3027 * 2 / sqrt(3) = 4.968
    assert mean == 12.0 and half == pytest.approx(4.968, abs=1e-3)
    assert t_interval([5.0]) == (5.0, None)
    assert t_interval([]) == (None, None)


def test_window_counts_and_fault_effect():
    assert window_counts([1.0, 29.9, 30.0, 95.0, 200.0], 120.0) == [2, 1, 0, 2]
    base = [float(t) for t in range(5, 300, 10)]  # one task per 10 s: 3 per window
    hit = [t for t in base if not 100 <= t < 160]  # nothing from 100 to 160 s
    eff = fault_effect(base, hit, fault_s=100.0, duration_s=300.0)
    assert eff["tasks_lost"] == 6
    assert eff["recovery_s"] == pytest.approx(80.0)  # window [180, 210) is the first full one
    assert fault_effect(base, base, 100.0, 300.0) == {"tasks_lost": 0, "recovery_s": 0.0}


def test_run_figures_of_a_record():
    m = {"robots": 4, "sim_time_s": 300.0, "task_times_s": [50.0, 130.0, 200.0, 290.0],
         "time_to_task_mean_s": 40.0, "time_to_task_p95_s": 70.0, "holding_time_s": 8.0,
         "coordinator_wait_s": 12.0, "collisions": {"robot_robot": 1, "robot_wall": 0},
         "late_ticks": 0, "rtf": 5.0, "tasks_completed": 4, "reproducible": True,
         "reservation_conflicts": 0,
         "tasks_per_robot": {"min": 0, "median": 1.0, "max": 2, "without_task": 1},
         "comm": {"messages_per_s": 0.5, "bytes_per_s": 1000.0,
                  "by_topic": {"map": {"messages": 4, "bytes": 240000},
                               "request": {"messages": 30, "bytes": 6000},
                               "assignment": {"messages": 60, "bytes": 12000}}}}
    f = run_figures({"exit_code": 0, "metrics": m, "cpu_per_robot": 0.02}, warmup_s=120.0)
    assert f["throughput"] == pytest.approx(3 / (180 / 3600))  # 3 tasks after 120 s
    assert f["holding_per_robot"] == pytest.approx(5.0)
    assert (f["idle_robots"], f["min_tasks"]) == (1, 0)
    assert f["collisions"] == 1 and f["cpu_per_robot_ms"] == pytest.approx(20.0)
    assert f["coord_msgs"] == pytest.approx(90 / 300) and f["coord_bytes"] == 60.0
    assert f["comm_bytes_per_robot"] == 250.0
    assert f["jain"] is None  # no robot_tasks in this record
    assert f["distance_per_task"] is None  # nor the robots' distances
    f = run_figures({"exit_code": 0, "metrics": {**m, "robot_tasks": [2, 1, 1, 0],
                                                 "robot_distance_m": [30.0, 20.0, 25.0, 5.0]}},
                    warmup_s=120.0)
    assert f["distance_per_task"] == pytest.approx(80.0 / 4)
    assert f["jain"] == pytest.approx(16 / (4 * 6))
    assert run_figures({"exit_code": 1, "metrics": m}, 120.0) is None


def test_time_to_task_with_the_open_tasks_counted_by_hand():
    """task_intervals: from one completion to the next (the first from the start), those
    ending after the warm-up, and every robot's open task at the end; km_quantiles: the
    Kaplan-Meier estimate worked by hand."""
    from swarm_bench.experiment_stats import km_quantiles, task_intervals

    done, still_open = task_intervals([[10.0, 50.0, 320.0, 400.0], [], [350.0]], 600.0, 300.0)
    assert sorted(done) == [80.0, 270.0, 350.0]
    assert sorted(still_open) == [200.0, 250.0, 600.0]  # the robot with no task counts too
    # six at risk: 80 done (S = 5/6); 200 and 250 open; 270 done of 3 (S = 5/9); 350 done of
    # 2 (S = 5/18): the median is 350 s, the 95th percentile never reached
    assert km_quantiles(done, still_open) == [350.0, None]
    # nothing open: the plain empirical quantiles
    assert km_quantiles([1.0, 2.0, 3.0, 4.0], []) == [2.0, 4.0]
    assert km_quantiles([], [5.0]) == [None, None]


def test_a_record_keeps_each_robots_task_times_and_distance():
    """records/<cell>-s<seed>.json keeps, per robot in robot order (Srobot2 before Srobot10),
    its tasks, when each was completed and the distance it drove."""
    from swarm_bench.experiment_plan import slim_record

    per = {"Srobot10": {"tasks": 1, "task_times_s": [70.5], "distance_m": 12.5},
           "Srobot2": {"tasks": 2, "task_times_s": [10.0, 40.25], "distance_m": 30.0}}
    plan = validate(build_parser().parse_args(
        ["--output", "unused", "--sizes", "20", "--no-faults", "--no-ablations"])).plan
    cell = plan.cells()[0]
    rec = slim_record({"exit_code": 0, "metrics": {"per_robot": per}}, cell, 0,
                      {"commit": "abc", "dirty": False, "diff_sha256": None}, {})
    m = rec["metrics"]
    assert m["robot_tasks"] == [2, 1]
    assert m["robot_task_times"] == [[10.0, 40.25], [70.5]]
    assert m["robot_distance_m"] == [30.0, 12.5]
    f = run_figures({**rec, "metrics": {**m, "robots": 2, "sim_time_s": 100.0,
                                        "tasks_completed": 3}}, warmup_s=20.0)
    assert f["distance_per_task"] == pytest.approx(42.5 / 3)
    # tasks ending after 20 s: 10 -> 40.25 (30.25 s) and 0 -> 70.5; open at 100 s: 59.75 and
    # 29.5 s. At risk 4; 29.5 open; 30.25 done of 3 (S = 2/3); 59.75 open; 70.5 done of 1 (S = 0)
    assert f["ttt_km_median"] == 70.5 and f["ttt_km_p95"] == 70.5


def test_paired_statistics_match_a_hand_computed_example():
    # A - B per seed: 2, 4, 3, 5, 6: mean 4, s = sqrt(2.5) = 1.5811, se = 0.70711,
    # t = 5.6569 on 4 df: p = 0.004805 (two-sided); t(0.975, 4) = 2.7764: half-width 1.9632.
    # Wilcoxon: all five differences positive, exact two-sided p = 2/32 = 0.0625.
    a = {0: 12.0, 1: 14.0, 2: 13.0, 3: 15.0, 4: 16.0}
    b = {0: 10.0, 1: 10.0, 2: 10.0, 3: 10.0, 4: 10.0, 5: 99.0}  # seed 5 has no pair
    st = paired(a, b)
    assert st["n"] == 5 and st["seeds"] == [0, 1, 2, 3, 4]
    assert st["diff"] == pytest.approx(4.0)
    assert st["ci95"] == pytest.approx(1.9632, abs=1e-4)
    assert st["p_t"] == pytest.approx(0.004805, abs=1e-5)
    assert st["p_wilcoxon"] == pytest.approx(0.0625)
    assert st["rel"] == pytest.approx(10.0 / 14.0 - 1.0)  # B's change against A
    same = paired({0: 1.0, 1: 2.0}, {0: 1.0, 1: 2.0})
    assert same["p_t"] == 1.0 and same["p_wilcoxon"] is None
    assert paired({0: 1.0}, {0: 0.5})["p_t"] is None  # one seed: no test


def test_holm_adjusts_by_rank_and_keeps_the_order_monotone():
    # m = 4: 0.01*4 = 0.04, 0.02*3 = 0.06, 0.03*2 = 0.06, 0.04*1 = 0.04 -> max so far: 0.06
    adj = holm([0.03, 0.01, None, 0.04, 0.02])
    assert adj[2] is None
    assert [adj[i] for i in (1, 4, 0, 3)] == pytest.approx([0.04, 0.06, 0.06, 0.06])
    assert holm([0.5, 0.9]) == pytest.approx([1.0, 1.0])


def test_littles_law_after_the_warm_up():
    # 4 robots, tasks after 100 s: 30 in 300 s, each 40 s: lambda W = 0.1 * 40 = 4 = N
    times = [100.0 + 10.0 * k for k in range(1, 31)]
    law = littles_law([50.0, *times], [999.0] + [40.0] * 30, 4, 100.0, 400.0)
    assert law["lambda_w"] == pytest.approx(4.0) and law["ratio"] == pytest.approx(1.0)


def test_defaults_cells_and_the_same_seeds_in_every_variant(tmp_path):
    cfg = validate(build_parser().parse_args(["--output", str(tmp_path / "x")]))
    plan = cfg.plan
    assert plan.sizes == (20, 50, 100) and plan.runs == 5 and plan.duration_s == 900.0
    assert plan.warmup_s == 300.0 and plan.ablation_size == 50 and plan.fault_size == 50
    # the three main arms: decentralized, the Open-RMF-like scheduler, the pipelined one
    assert plan.variants == ("decentralized", "centralized-scheduler", "centralized-pipelined")
    assert plan.faults == ("kill-robot:3@360", "kill-coordinator@360+30")
    labels = [c.label for c in plan.cells()]
    assert labels[:3] == ["decentralized-n20", "centralized-scheduler-n20",
                          "centralized-pipelined-n20"]
    assert labels[9:12] == ["decentralized-no-swap-n50", "centralized-fifo-hall-n50",
                            "centralized-scheduler-hall-n50"]
    # the coordinator's death runs only where there is a coordinator
    assert labels[12:] == ["decentralized-n50-f1", "centralized-scheduler-n50-f1",
                           "centralized-pipelined-n50-f1", "centralized-scheduler-n50-f2",
                           "centralized-pipelined-n50-f2"]
    runs = plan.runs_in_order()
    assert len(runs) == 17 * 5
    seeds = {}
    for cell, seed in runs:
        seeds.setdefault(cell.label, []).append(seed)
    assert set(map(tuple, seeds.values())) == {(0, 1, 2, 3, 4)}
    none = validate(build_parser().parse_args(["--output", str(tmp_path / "w"), "--no-faults",
                                               "--no-ablations", "--sizes", "5"]))
    assert [c.label for c in none.plan.cells()] == ["decentralized-n5",
                                                    "centralized-scheduler-n5",
                                                    "centralized-pipelined-n5"]
    assert plan_from_settings(plan.settings()) == plan


def test_variants_record_their_overrides_and_pass_them_to_swarm_up(tmp_path):
    cfg = validate(build_parser().parse_args(["--output", str(tmp_path / "x")]))
    cells = {c.label: c for c in cfg.plan.cells()}
    assert variant_args(tmp_path, cells["decentralized-n20"]) == ()
    assert variant_args(tmp_path, cells["centralized-scheduler-n20"]) == (
        "--assignment", "nearest-free", "--waiting-spots", "near")
    assert variant_args(tmp_path, cells["centralized-fifo-hall-n50"]) == (
        "--assignment", "route", "--waiting-spots", "hall")
    no_swap = variant_args(tmp_path, cells["decentralized-no-swap-n50"])
    assert no_swap[0] == "--nav-params"
    import yaml

    params = yaml.safe_load(Path(no_swap[1]).read_text())["navigator"]["ros__parameters"]
    assert params["swap_range"] == 0.0 and params["congestion_limit"] > 0  # only that one
    assert variant_args(tmp_path, cells["centralized-scheduler-n50-f2"])[-2:] == (
        "--faults", "kill-coordinator@360+30")
    assert nav_params_file(tmp_path, VARIANTS["decentralized"]) is None
    settings = cfg.plan.settings()
    assert settings["overrides"]["decentralized-no-swap"]["navigator"] == {"swap_range": 0.0}
    assert settings["overrides"]["centralized-fifo-hall"]["swarm_up"] == [
        "--assignment", "route", "--waiting-spots", "hall"]


def test_shards_partition_the_runs(tmp_path):
    plan = validate(build_parser().parse_args(["--output", str(tmp_path / "x")])).plan
    runs = plan.runs_in_order()
    shards = [[k for k in range(len(runs)) if k % 3 == i - 1] for i in (1, 2, 3)]
    assert sorted(sum(shards, [])) == list(range(len(runs)))
    assert all(abs(len(a) - len(b)) <= 1 for a in shards for b in shards)


# ----------------------------------------------------- records -> report, without simulating
def fake_record(label, variant, mode, size, seed, tasks_per_100s, role="main", fault=""):
    times = [round(100.0 / tasks_per_100s * (k + 1), 3)
             for k in range(int(tasks_per_100s * 9))]
    m = {"robots": size, "sim_time_s": 900.0, "task_times_s": times,
         "task_durations_s": [40.0 + (k % 5) for k in range(len(times))],
         "time_to_task_mean_s": 42.0, "time_to_task_p95_s": 44.0, "holding_time_s": 10.0,
         "coordinator_wait_s": None, "collisions": {"robot_robot": 0, "robot_wall": 0},
         "late_ticks": 0, "rtf": 3.0, "tasks_completed": len(times), "reproducible": True,
         "reservation_conflicts": 0, "coordination": mode, "min_separation_m": 0.1,
         "tasks_per_robot": {"min": 1, "median": 2.0, "max": 3, "without_task": 0},
         "robot_tasks": [len(times) // size] * size,
         "standstills": [{"robot": "Srobot1", "start_s": 10.0, "duration_s": 70.0, "x": -5.6,
                          "y": 1.1, "open": False}],
         "comm": {"messages_per_s": 0.5, "bytes_per_s": 1000.0, "by_topic": {}}}
    return {"label": label, "variant": variant, "mode": mode, "size": size, "fault": fault,
            "role": role, "seed": seed, "command": ["swarm-up", "--seed", str(seed)],
            "exit_code": 0, "error": None, "cpu_s": 10.0, "cpu_per_robot": 0.01,
            "commit": "abc123", "dirty": False,
            "machine": {"cores": 2, "cpu_model": "Test CPU", "python": "3.11",
                        "ros_distro": "jazzy", "rclpy": "7.1.6", "fastdds": "2.14.5",
                        "platform": "Linux"},
            "started": f"2026-11-27T03:00:0{seed}+00:00",
            "finished": f"2026-11-27T03:10:0{seed}+00:00", "metrics": m}


def write_fake_sweep(out, sizes=(20,), seeds=range(5), rates=None, missing=(),
                     ablations=False):
    from swarm_bench.bench import _write_json

    argv = ["--output", str(out), *TWO_ARMS, "--sizes", ",".join(map(str, sizes)), "--no-faults",
            "--warmup", "300", *(["--ablation-size", str(sizes[0])] if ablations
                                 else ["--no-ablations"])]
    plan = validate(build_parser().parse_args(argv)).plan
    (out / "records").mkdir(parents=True, exist_ok=True)
    _write_json(out / "plan.json", {"settings": plan.settings()})
    rates = rates or {"decentralized": [3.0, 3.2, 2.9, 3.1, 3.3],
                      "centralized-scheduler": [2.0, 2.4, 2.1, 2.2, 2.0]}
    for cell, seed in plan.runs_in_order():
        if (cell.label, seed) in missing:
            continue
        rec = fake_record(cell.label, cell.variant, cell.mode, cell.size, seed,
                          rates[cell.variant][seed])
        _write_json(record_path(out, cell.label, seed), rec)
    return plan


def test_report_is_rebuilt_byte_for_byte_from_its_json(tmp_path):
    from swarm_bench.experiment_report import write_report

    a, b, c = tmp_path / "a", tmp_path / "b", tmp_path / "c"
    write_fake_sweep(a)
    first = write_report([a], b)
    assert first["records"] == 10 and first["missing"] == 0
    c.mkdir()
    (c / "experiment.json").write_bytes((b / "experiment.json").read_bytes())
    write_report([c], c)  # from the JSON alone
    for name in ("report.md", "experiment.json", "throughput.png", "throughput.svg",
                 "tasks_over_time.svg", "time_to_task_ecdf.png"):
        assert (b / name).read_bytes() == (c / name).read_bytes(), name
    report = (b / "report.md").read_text()
    assert "Test CPU, 2 cores" in report and "Fast DDS 2.14.5" in report
    assert "rclpy 7.1.6" in report and "`abc123`" in report
    zero = next(line for line in report.splitlines() if line.startswith("Zero in every run"))
    assert "collisions (robot-robot + wall)" in zero and "late ticks" in zero
    doc = json.loads((b / "experiment.json").read_text())
    row = next(r for r in doc["statistics"] if r["measure"] == "throughput")
    assert (row["a"], row["b"], row["n"]) == ("decentralized-n20",
                                              "centralized-scheduler-n20", 5)
    assert row["claim"] and row["p_holm"] >= row["p_t"]
    assert (b / "throughput.png").read_bytes()[:8] == PNG_MAGIC


def test_a_comparison_over_fewer_than_five_seeds_claims_nothing(tmp_path):
    from swarm_bench.experiment_report import write_report

    missing = {(f"{v}-n20", s) for v in ("decentralized", "centralized-scheduler")
               for s in (3, 4)}
    write_fake_sweep(tmp_path / "a", missing=missing)
    write_report([tmp_path / "a"], tmp_path / "a")
    doc = json.loads((tmp_path / "a" / "experiment.json").read_text())
    row = next(r for r in doc["statistics"] if r["measure"] == "throughput")
    assert row["n"] == 3 and row["p_holm"] < 0.05 and row["claim"] is False
    assert "| no (< 5 seeds) |" in (tmp_path / "a" / "report.md").read_text()


def test_jains_index_by_hand():
    from swarm_bench.experiment_stats import jain

    assert jain([3, 3, 3, 3]) == 1.0
    assert jain([4, 0, 0, 0]) == 0.25  # one robot did everything: 1/n
    assert jain([1, 2, 3]) == pytest.approx(36 / (3 * 14))
    assert jain([0, 0]) is None


def test_fairness_is_co_primary_in_the_holm_family(tmp_path, monkeypatch):
    """Jain's index of the tasks per robot and the robots without a task are tested for the
    main pair beside throughput, adjusted with every other comparison (Holm), and shown in the
    primary section with their values."""
    import tests.swarm_bench.test_experiment as me
    from swarm_bench.experiment_report import write_report

    def uneven(label, variant, mode, size, seed, rate, make=fake_record, **kw):
        rec = make(label, variant, mode, size, seed, rate, **kw)
        if mode == "decentralized":  # half the robots do all the work, the others none
            counts = [2] * (size // 2) + [0] * (size - size // 2)
        else:
            counts = [1] * size
        rec["metrics"]["robot_tasks"] = counts
        rec["metrics"]["tasks_per_robot"] = {**rec["metrics"]["tasks_per_robot"],
                                             "without_task": counts.count(0)}
        return rec

    monkeypatch.setattr(me, "fake_record", uneven)
    write_fake_sweep(tmp_path / "a")
    write_report([tmp_path / "a"], tmp_path / "a")
    doc = json.loads((tmp_path / "a" / "experiment.json").read_text())
    rows = {r["measure"]: r for r in doc["statistics"] if r["role"] == "main"}
    assert {"throughput", "jain", "idle_robots"} <= set(rows)
    assert rows["jain"]["diff"] == pytest.approx(0.5 - 1.0)  # half the robots: 1/2 against 1
    assert rows["idle_robots"]["diff"] == 10.0
    ps = [r["p_t"] for r in doc["statistics"]]
    assert rows["jain"]["p_holm"] >= rows["jain"]["p_t"] and len(ps) >= 6
    report = (tmp_path / "a" / "report.md").read_text()
    primary = report.split("## Primary measures")[1].split("## Secondary")[0]
    assert "| decentralized | 0.500 ± 0.000, 10.0 ± 0.0 |" in primary
    assert "| Jain's index of tasks per robot | 5 |" in primary
    assert "| robots without a task | 5 |" in primary


def test_the_secondary_tests_count_the_open_tasks_where_the_records_allow(tmp_path,
                                                                         monkeypatch):
    """With each robot's task times and the waiting per task in every record, the main pair's
    secondary tests are the Kaplan-Meier time to task (open tasks counted) and the waiting per
    task; records without them keep the completed tasks' mean and 95th percentile and the
    holding + waiting (the same number of tests either way)."""
    import tests.swarm_bench.test_experiment as me
    from swarm_bench.experiment_report import SECONDARY, SECONDARY_UNCENSORED, write_report

    def timed(label, variant, mode, size, seed, rate, make=fake_record, **kw):
        rec = make(label, variant, mode, size, seed, rate, **kw)
        period = 40.0 if mode == "decentralized" else 70.0  # every robot, one task per period
        rec["metrics"]["robot_task_times"] = [
            [period * k for k in range(1, int(900 // period) + 1)]] * size
        rec["metrics"]["waiting_per_task_s"] = 5.0 if mode == "decentralized" else 9.0
        return rec

    write_fake_sweep(tmp_path / "old")
    write_report([tmp_path / "old"], tmp_path / "old")
    old = json.loads((tmp_path / "old" / "experiment.json").read_text())
    monkeypatch.setattr(me, "fake_record", timed)
    write_fake_sweep(tmp_path / "new")
    write_report([tmp_path / "new"], tmp_path / "new")
    new = json.loads((tmp_path / "new" / "experiment.json").read_text())
    measures = {doc_name: [r["measure"] for r in doc["statistics"] if r["role"] == "main"]
                for doc_name, doc in (("old", old), ("new", new))}
    assert measures["old"][3:] == list(SECONDARY_UNCENSORED)
    assert measures["new"][3:] == list(SECONDARY)
    rows = {r["measure"]: r for r in new["statistics"] if r["role"] == "main"}
    # every interval after the warm-up is one period; the open ones are shorter (censored)
    assert rows["ttt_km_median"]["diff"] == pytest.approx(40.0 - 70.0)
    assert rows["ttt_km_p95"]["diff"] == pytest.approx(40.0 - 70.0)
    assert rows["waiting_per_task"]["diff"] == pytest.approx(5.0 - 9.0)
    report = (tmp_path / "new" / "report.md").read_text()
    tests = report.split("### Paired differences of the secondary measures")[1]
    assert "| time to task after warm-up, open tasks counted: median [s] | 5 |" in tests
    assert "holding + waiting" not in tests.split("##")[0]


def test_the_ablation_chain_adds_up_to_the_whole_gap(tmp_path):
    from swarm_bench.experiment_report import write_report

    rates = {"decentralized": [3.0] * 5, "decentralized-no-swap": [2.8] * 5,
             "centralized-fifo-hall": [2.0] * 5, "centralized-scheduler-hall": [2.2] * 5,
             "centralized-scheduler": [2.4] * 5}
    write_fake_sweep(tmp_path / "a", rates=rates, ablations=True)
    write_report([tmp_path / "a"], tmp_path / "a")
    report = (tmp_path / "a" / "report.md").read_text()
    # tasks after the 300 s warm-up, over 600 s: rate 3.0 -> 27 tasks every 33.3 s, 18 after
    # 300 s: 108/h; 2.8 -> 17: 102/h; 2.0 -> 12: 72/h; 2.2 -> 13: 78/h; 2.4 -> 14: 84/h
    line = next(x for x in report.splitlines() if x.startswith("The chain decentralized"))
    assert "whole gap of +24 tasks/h" in line
    assert "taking another workstation (decentralized) +6 tasks/h (25 %)" in line
    assert "queues in the hall) +30 tasks/h (125 %)" in line
    assert "the scheduler's assignment -6 tasks/h (-25 %)" in line
    assert "instead of the hall -6 tasks/h (-25 %)" in line


def write_fault_sweep(out: Path, cost: dict[str, int]) -> None:
    """A fake sweep of ``cost``'s variants at 20 robots with a dead robot at 360 s
    (``kill-robot:3@360``): every run completes a task every 1/3.0 s (:func:`fake_record`), and
    the faulted run of variant v and seed s misses the first ``cost[v] * (s + 1)`` tasks after
    the fault."""
    from swarm_bench.bench import _write_json

    argv = ["--output", str(out), "--variants", ",".join(cost), "--sizes", "20",
            "--no-ablations", "--fault-spec", "kill-robot:3@360", "--fault-size", "20",
            "--warmup", "300"]
    plan = validate(build_parser().parse_args(argv)).plan
    (out / "records").mkdir(parents=True)
    _write_json(out / "plan.json", {"settings": plan.settings()})
    for cell, seed in plan.runs_in_order():
        rec = fake_record(cell.label, cell.variant, cell.mode, cell.size, seed, 3.0,
                          cell.role, cell.fault)
        if cell.fault:  # drop the first tasks after the fault
            times = rec["metrics"]["task_times_s"]
            drop = [t for t in times if t >= 360][:cost[cell.variant] * (seed + 1)]
            rec["metrics"]["task_times_s"] = [t for t in times if t not in drop]
        _write_json(record_path(out, cell.label, seed), rec)


def test_faults_are_tested_paired_per_mode_and_between_the_modes(tmp_path):
    """A dead robot at 360 s costs decentralized seed s s + 1 tasks, centralized 2 (s + 1):
    hand-computed, tasks lost 3 and 6 on average, decentralized 3 fewer (per seed 1..5)."""
    from swarm_bench.experiment_report import write_report

    out = tmp_path / "a"
    write_fault_sweep(out, {"decentralized": 1, "centralized-scheduler": 2})
    write_report([out], out)
    rows = [r for r in json.loads((out / "experiment.json").read_text())["statistics"]
            if r["role"] == "fault"]
    by = {(r["a"], r["measure"]): r for r in rows}
    dec = by[("decentralized-n20", "tasks after the fault")]
    cen = by[("centralized-scheduler-n20", "tasks after the fault")]
    assert (dec["b"], dec["diffs"], cen["diffs"]) == (
        "decentralized-n20-f1", [1.0, 2.0, 3.0, 4.0, 5.0], [2.0, 4.0, 6.0, 8.0, 10.0])
    between = by[("decentralized-n20-f1", "tasks lost to the fault")]
    assert between["b"] == "centralized-scheduler-n20-f1"
    assert between["diffs"] == [-1.0, -2.0, -3.0, -4.0, -5.0] and between["diff"] == -3.0
    # t = -3 / (sqrt(2.5) / sqrt(5)) = -4.243 with 4 degrees of freedom: p = 0.0132
    assert abs(between["p_t"] - 0.0132) < 5e-4 and len(rows) == 3
    assert all(r["p_holm"] >= r["p_t"] for r in rows)
    report = (out / "report.md").read_text()
    assert "### Paired tests of the faults" in report
    # no "B vs A" for two losses (here it would read +100 %): their ratio says nothing
    assert between["rel"] is None
    assert "| decentralized-n20-f1 | centralized-scheduler-n20-f1 (kill-robot:3@360) | " \
           "tasks lost to the fault | 5 | -3.0 ± 2.0 | - |" in report


def test_with_three_arms_the_tasks_lost_are_tested_against_each_centralized_arm(tmp_path):
    """Decentralized loses s + 1 tasks to the fault, the scheduler 2 (s + 1), the pipelined arm
    3 (s + 1) (seed s = 0..4): decentralized loses 3 fewer than the scheduler and 6 fewer than
    the pipelined arm on average, per seed -1..-5 and -2..-10."""
    from swarm_bench.experiment_report import write_report

    out = tmp_path / "a"
    write_fault_sweep(out, {"decentralized": 1, "centralized-scheduler": 2,
                            "centralized-pipelined": 3})
    write_report([out], out)
    rows = [r for r in json.loads((out / "experiment.json").read_text())["statistics"]
            if r["role"] == "fault" and r["measure"] == "tasks lost to the fault"]
    assert [(r["a"], r["b"]) for r in rows] == [
        ("decentralized-n20-f1", "centralized-scheduler-n20-f1"),
        ("decentralized-n20-f1", "centralized-pipelined-n20-f1")]
    assert rows[0]["diffs"] == [-1.0, -2.0, -3.0, -4.0, -5.0]
    assert rows[1]["diffs"] == [-2.0, -4.0, -6.0, -8.0, -10.0] and rows[1]["diff"] == -6.0


def test_shards_merge_into_one_report(tmp_path):
    from swarm_bench.experiment_report import write_report

    whole, s1, s2, out1, out2 = (tmp_path / n for n in ("w", "s1", "s2", "o1", "o2"))
    plan = write_fake_sweep(whole)
    runs = plan.runs_in_order()
    write_fake_sweep(s1, missing={(c.label, s) for k, (c, s) in enumerate(runs) if k % 2})
    write_fake_sweep(s2, missing={(c.label, s) for k, (c, s) in enumerate(runs)
                                  if not k % 2})
    assert write_report([s1, s2], out1)["missing"] == 0
    write_report([whole], out2)
    assert (out1 / "report.md").read_bytes() == (out2 / "report.md").read_bytes()
    partial = write_report([s1], tmp_path / "p")
    assert partial["missing"] == 5
    assert "This report is partial" in (tmp_path / "p" / "report.md").read_text()


def test_resume_skips_the_runs_it_has_and_runs_only_its_shard(tmp_path, monkeypatch):
    import swarm_bench.bench as bench
    from swarm_bench import experiment

    out = tmp_path / "x"
    plan = write_fake_sweep(out, missing={("centralized-scheduler-n20", 3)})
    ran = []

    def fake_run(bcfg, n, r, stop, view):
        ran.append((n, bcfg.seed, bcfg.coordination, bcfg.extra_args))
        return {**fake_record("?", "?", bcfg.coordination, n, bcfg.seed, 2.0),
                "interrupted": False}

    monkeypatch.setattr(bench, "run_swarm_up", fake_run)
    argv = ["--resume", str(out), *TWO_ARMS, "--sizes", "20", "--no-faults", "--no-ablations"]
    cfg = validate(build_parser().parse_args(argv))
    assert experiment.experiment(cfg, argv) == 0
    assert ran == [(20, 3, "centralized", ("--assignment", "nearest-free",
                                          "--waiting-spots", "near"))]
    assert (record_path(out, "centralized-scheduler-n20", 3)).is_file()
    # a shard runs its own slice only: runs 1, 3, 5, 7, 9 of 10 (k % 2 == 1)
    ran.clear()
    fresh = tmp_path / "y"
    argv = ["--output", str(fresh), *TWO_ARMS, "--sizes", "20", "--no-faults", "--no-ablations",
            "--shard", "2/2"]
    assert experiment.experiment(validate(build_parser().parse_args(argv)), argv) == 0
    expected = [(c.size, s) for k, (c, s) in enumerate(plan.runs_in_order()) if k % 2 == 1]
    assert [(n, seed) for n, seed, _, _ in ran] == expected


def test_only_runs_the_blocks_named_and_keeps_the_plan_whole(tmp_path, monkeypatch):
    import swarm_bench.bench as bench
    from swarm_bench import experiment

    ran = []

    def fake_run(bcfg, n, r, stop, view):
        ran.append((n, bcfg.seed, bcfg.extra_args))
        return {**fake_record("?", "?", bcfg.coordination, n, bcfg.seed, 2.0),
                "interrupted": False}

    monkeypatch.setattr(bench, "run_swarm_up", fake_run)
    base = [*TWO_ARMS, "--sizes", "20,50", "--runs", "2", "--no-faults", "--no-ablations",
            "--service-times", "60"]
    out = tmp_path / "x"
    argv = ["--output", str(out), *base, "--only", "main:50,service"]
    cfg = validate(build_parser().parse_args(argv))
    assert experiment.experiment(cfg, argv) == 0  # every run of its blocks ended well
    # 2 variants x 2 seeds at 50 robots, then the same with a service time of 60 s
    assert [n for n, _, _ in ran] == [50] * 8
    assert sum("--service-time" in a for _, _, a in ran) == 4
    assert not any(n == 20 for n, _, _ in ran)
    # the other block follows with --resume under the same plan
    ran.clear()
    argv = ["--resume", str(out), *base]
    assert experiment.experiment(validate(build_parser().parse_args(argv)), argv) == 0
    assert [n for n, _, _ in ran] == [20] * 4
    res = subprocess.run([str(SWARM_EXPERIMENT), "--output", str(tmp_path / "z"),
                          "--only", "main:x"], capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "--only" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_resume_with_another_plan_is_refused(tmp_path):
    out = tmp_path / "x"
    write_fake_sweep(out)
    res = subprocess.run([str(SWARM_EXPERIMENT), "--resume", str(out), *TWO_ARMS, "--sizes",
                          "20", "--no-faults", "--no-ablations", "--runs", "3"],
                         capture_output=True, text=True, timeout=60)
    assert res.returncode == 2 and "--resume" in res.stderr and "runs" in res.stderr
    assert len(res.stderr.strip().splitlines()) == 1


def test_report_command_rebuilds_from_records(tmp_path):
    out = tmp_path / "x"
    write_fake_sweep(out)
    res = subprocess.run([str(SWARM_EXPERIMENT), "report", str(out)], capture_output=True,
                         text=True, timeout=120)
    assert res.returncode == 0, res.stderr
    assert (out / "report.md").is_file() and "10 runs" in res.stdout
    bad = subprocess.run([str(SWARM_EXPERIMENT), "report", str(tmp_path / "nothing")],
                         capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "DIR" in bad.stderr
    assert len(bad.stderr.strip().splitlines()) == 1


@pytest.mark.parametrize(("args", "flag"), [
    (["--sizes", "0"], "--sizes"),
    (["--runs", "0"], "--runs"),
    (["--variants", "central"], "--variants"),
    (["--world", "nowhere"], "--world"),
    (["--warmup", "1000"], "--warmup"),
    (["--shard", "3/2"], "--shard"),
    (["--shard", "x"], "--shard"),
    (["--resume", "nowhere"], "--resume"),
    (["--fault-spec", " "], "--fault-spec"),
    (["--fault-spec", "kill_robot Srobot2 at 300"], "--fault-spec"),
    (["--fault-spec", "kill-robot:51@60"], "--fault-spec"),  # 50 robots in the fault runs
    (["--fault-spec", "kill-robot:3@1000"], "--fault-spec"),  # after the 900 s run
    (["--fault-spec", "kill-coordinator@60", "--variants", "decentralized"], "--fault-spec"),
    (["--fault-spec", "kill-robot:3@60", "--no-faults"], "--no-faults"),
    (["--service-times", "15,soon"], "--service-times"),
    (["--service-times", "-5"], "--service-times"),
    (["--service-size", "50"], "--service-size"),
    (["--fault-spec", "kill-robot:@dock@360"], "--fault-spec"),
    (["--bogus"], "--bogus"),
])
def test_bad_flag_exits_2_with_one_line(args, flag, tmp_path):
    res = subprocess.run([str(SWARM_EXPERIMENT), *args], capture_output=True, text=True,
                         cwd=tmp_path, timeout=60)
    assert res.returncode == 2, res.stderr
    lines = res.stderr.strip().splitlines()
    assert len(lines) == 1 and flag in lines[0] and "Traceback" not in res.stderr, res.stderr


def test_help_exits_0():
    for argv in (["--help"], ["report", "--help"]):
        res = subprocess.run([str(SWARM_EXPERIMENT), *argv], capture_output=True, text=True,
                             timeout=60)
        assert res.returncode == 0 and ("--shard" in res.stdout or "DIR" in res.stdout)


@pytest.mark.e2e
def test_tiny_sweep_writes_the_report(tmp_path):
    out = tmp_path / "report"
    # one size (several sizes in one report: the fake sweeps above), both modes, a fault
    argv = [str(SWARM_EXPERIMENT), *TWO_ARMS, "--sizes", "2", "--duration", "12", "--runs", "2",
            "--warmup", "5", "--output", str(out), "--no-ablations", "--allow-dirty",
            "--fault-spec", "kill-coordinator@8+3", "--fault-size", "2"]
    res = subprocess.run(argv, capture_output=True, text=True, cwd=tmp_path, timeout=1500)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    doc = json.loads((out / "experiment.json").read_text())
    assert len(doc["records"]) == 6
    assert {r["label"] for r in doc["records"]} == {
        "decentralized-n2", "centralized-scheduler-n2", "centralized-scheduler-n2-f1"}
    assert sorted({r["seed"] for r in doc["records"]}) == [0, 1]
    assert all(r["metrics"]["coordination"] == r["mode"] for r in doc["records"])
    assert all("--assignment" in r["command"] for r in doc["records"]
               if r["mode"] == "centralized")
    faulted = [r["metrics"] for r in doc["records"]
               if r["label"] == "centralized-scheduler-n2-f1"]
    assert all(m["faults"] == 1 and m["restarts"] == 1 for m in faulted)  # killed, restarted
    assert len(doc["summary"]) == 3 and all(s["runs_ok"] == 2 for s in doc["summary"])
    report = (out / "report.md").read_text()
    assert "- centralized-scheduler: tasks lost" in report
    assert doc["records"][0]["commit"] in report
    for png in ("throughput.png", "ttt_mean.png", "tasks_over_time.png",
                "time_to_task_ecdf.png", "tasks_per_robot.png"):
        assert (out / png).read_bytes()[:8] == PNG_MAGIC
        assert (out / png.replace(".png", ".svg")).is_file()
        assert f"]({png})" in report
    assert "report:" in res.stdout
    # one seed of every cell again at this commit: the same task times (reproducible runs)
    res = subprocess.run([str(SWARM_EXPERIMENT), "recheck", str(out), "--allow-dirty"],
                         capture_output=True, text=True, cwd=tmp_path, timeout=900)
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-3000:]
    assert len(list((out / "recheck").glob("*.json"))) == 3
    report = (out / "report.md").read_text()
    assert "one seed of 3 cells; task times identical to the records' in 3 of 3" in report


def test_a_report_of_several_commits_says_whether_a_re_run_checked_them(tmp_path):
    from swarm_bench.bench import _write_json
    from swarm_bench.experiment_report import RECHECK, recheck_table, write_report

    plan = write_fake_sweep(tmp_path / "a")
    out = tmp_path / "a"
    first = record_path(out, "decentralized-n20", 0)
    rec = json.loads(first.read_text())
    rec["commit"] = "def456"
    _write_json(first, rec)
    write_report([out], out)
    assert "runs from 2 commits and no re-run check" in (out / "report.md").read_text()
    (out / RECHECK).mkdir()
    for cell in plan.cells():
        again = json.loads(record_path(out, cell.label, 0).read_text())
        again["commit"] = "fff000"
        if cell.variant == "centralized-scheduler":
            again["metrics"]["task_times_s"] = again["metrics"]["task_times_s"][1:]
        _write_json(out / RECHECK / f"{cell.label}-s0.json", again)
    write_report([out], out)
    report = (out / "report.md").read_text()
    assert ("re-run at `fff000`: one seed of 2 cells; task times identical to the records' "
            "in 1 of 2 (they differ in centralized-scheduler-n20 seed 0)") in report
    doc = json.loads((out / "experiment.json").read_text())
    assert [r["identical"] for r in doc["recheck_table"]] == [False, True]
    c = tmp_path / "c"
    c.mkdir()
    (c / "experiment.json").write_bytes((out / "experiment.json").read_bytes())
    write_report([c], c)
    assert (c / "report.md").read_bytes() == (out / "report.md").read_bytes()
    assert recheck_table([], doc["rechecks"]) == []


COMMITTED_WORLDS = sorted(
    d.name for d in (Path(__file__).resolve().parents[2] / "docs" / "experiments").iterdir()
    if (d / "experiment.json").is_file())


def test_the_committed_experiments_include_the_default_world():
    assert "slim_blockage" in COMMITTED_WORLDS


@pytest.mark.parametrize("world", COMMITTED_WORLDS)
def test_the_committed_report_is_rebuilt_from_its_json(world, tmp_path):
    """docs/experiments/<world>/: report.md, experiment.json and every figure (PNG and SVG)
    are what ``swarm-experiment report`` makes of the committed experiment.json, byte for byte
    (the test extra pins the matplotlib that drew them)."""
    from swarm_bench.experiment_report import write_report

    committed = Path(__file__).resolve().parents[2] / "docs" / "experiments" / world
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "experiment.json").write_bytes(
        (committed / "experiment.json").read_bytes())
    write_report([tmp_path / "in"], tmp_path / "out")
    for name in ("report.md", "experiment.json"):
        assert (tmp_path / "out" / name).read_bytes() == (committed / name).read_bytes(), name
    figures = json.loads((committed / "experiment.json").read_text())["figures"].values()
    assert figures
    for fig in figures:
        for name in (fig, str(Path(fig).with_suffix(".svg"))):
            assert (tmp_path / "out" / name).read_bytes() == (committed / name).read_bytes(), name


def test_a_service_time_sweep_of_three_arms_is_planned_run_and_tested(tmp_path):
    """--service-times 15,60 at 20 robots: every main variant (here all three arms) once more
    per service time (the world's own, 0 s, is the main cell); swarm-up gets --service-time;
    the report tests decentralized against each centralized arm at each service time (in the
    Holm family) and rebuilds byte for byte from its JSON."""
    from swarm_bench.bench import _write_json
    from swarm_bench.experiment_report import write_report

    arms = "decentralized,centralized-scheduler,centralized-pipelined"
    argv = ["--output", str(tmp_path / "a"), "--sizes", "20", "--no-faults", "--no-ablations",
            "--variants", arms, "--service-times", "0,15,60"]
    plan = validate(build_parser().parse_args(argv)).plan
    assert plan.service_times == (15.0, 60.0) and plan.service_size == 20
    cells = {c.label: c for c in plan.cells()}
    assert [c.label for c in plan.cells() if c.role == "service"] == [
        f"{v}-n20-w{t}" for t in (15, 60) for v in arms.split(",")]
    assert variant_args(tmp_path, cells["centralized-pipelined-n20-w60"]) == (
        "--policy", "pipelined", "--queue-at", "holding", "--assignment", "nearest-free",
        "--service-time", "60")
    assert variant_args(tmp_path, cells["decentralized-n20"]) == ()
    assert plan_from_settings(plan.settings()) == plan
    out = tmp_path / "a"
    (out / "records").mkdir(parents=True)
    _write_json(out / "plan.json", {"settings": plan.settings()})
    # decentralized loses to the pipelined arm as the service time grows
    base = {"decentralized": 3.0, "centralized-scheduler": 2.0, "centralized-pipelined": 2.8}
    slope = {"decentralized": -0.02, "centralized-scheduler": -0.01,
             "centralized-pipelined": -0.005}
    for cell, seed in plan.runs_in_order():
        rate = base[cell.variant] + slope[cell.variant] * (cell.service or 0) + 0.1 * seed
        _write_json(record_path(out, cell.label, seed),
                    fake_record(cell.label, cell.variant, cell.mode, cell.size, seed, rate,
                                role=cell.role))
    write_report([out], out)
    doc = json.loads((out / "experiment.json").read_text())
    service = [r for r in doc["statistics"] if r["role"] == "service"]
    assert {(r["b"], r["measure"]) for r in service} >= {
        ("centralized-pipelined-n20-w60", "throughput"), ("centralized-scheduler-n20-w15", "jain")}
    # 15 and 60 s x 2 arms x 3 measures; 0 s, the world's own, is the main pairs, tested once
    assert len(service) == 2 * 2 * 3
    tested = [(r["a"], r["b"], r["measure"]) for r in doc["statistics"]]
    assert len(tested) == len(set(tested))
    row = next(r for r in service if r["b"] == "centralized-pipelined-n20-w60"
               and r["measure"] == "throughput")
    assert row["a"] == "decentralized-n20-w60" and -30.0 < row["diff"] < -20.0
    assert all(r["p_holm"] is None or r["p_holm"] >= r["p_t"] for r in doc["statistics"])
    main = {(r["a"], r["b"]) for r in doc["statistics"] if r["role"] == "main"}
    assert main == {("decentralized-n20", "centralized-scheduler-n20"),
                    ("decentralized-n20", "centralized-pipelined-n20")}
    report = (out / "report.md").read_text()
    section = report.split("## Service time")[1].split("## Secondary")[0]
    assert "| 0 s: throughput, Jain, without a task | 15 s:" in section
    assert "![service time](service_time.png)" in section
    assert "| centralized-scheduler-n20 (the world's service time) | Jain's index" in section
    # the main tables keep to the main cells
    primary = report.split("## Primary measures")[1].split("## Service time")[0]
    assert "-w15" not in primary
    c = tmp_path / "c"
    c.mkdir()
    (c / "experiment.json").write_bytes((out / "experiment.json").read_bytes())
    write_report([c], c)
    for name in ("report.md", "experiment.json", "service_time.png", "service_time.svg"):
        assert (out / name).read_bytes() == (c / name).read_bytes(), name
    # the headline table reads the same figures back: one row per arm and service time
    res = subprocess.run([str(SWARM_EXPERIMENT), "table", str(c)], capture_output=True,
                         text=True, timeout=60)
    assert res.returncode == 0, res.stderr
    rows = [line.split(" | ") for line in res.stdout.splitlines()
            if line.startswith("| ") and "robots" not in line]
    assert [(r[2], r[3]) for r in rows] == [
        (t, v) for t in ("0", "15", "60") for v in arms.split(",")]
    pipelined60 = next(r for r in rows if r[2] == "60" and r[3] == "centralized-pipelined")
    summary = next(s for s in doc["summary"] if s["label"] == "centralized-pipelined-n20-w60")
    assert pipelined60[5] == (f"{summary['throughput']['mean']:.0f} ± "
                              f"{summary['throughput']['ci95']:.0f}")
    assert pipelined60[6] == (f"{row['diff']:.0f} ± {row['ci95']:.0f}, "
                              f"{row['p_holm']:.3f} (5)")
    assert rows[0][6] == "-"  # the reference is not compared with itself
    bad = subprocess.run([str(SWARM_EXPERIMENT), "table", str(tmp_path)], capture_output=True,
                         text=True, timeout=60)
    assert bad.returncode == 2 and "DIR" in bad.stderr and "Traceback" not in bad.stderr


def test_a_placed_victim_is_read_off_the_no_fault_run_of_the_same_seed(tmp_path):
    """``kill-robot:@station@3``: the robot nearest a docking pose at 3 s in the no-fault run
    of that seed and variant; @approach the one nearest 1.5 m from one, @hall the farthest;
    two placed faults of one spec get two robots; an unknown placement is a bad flag."""
    from swarm_bench.experiment import fault_for, run_dir_of
    from swarm_bench.experiment_faults import choose_victim
    from swarm_scene.poi import poi_for_world
    from swarm_scene.world import resolve_world

    docks = np.array([[0.0, 0.0], [10.0, 0.0]])
    xy = np.array([[5.0, 5.0], [0.1, 0.0], [1.4, 0.3], [20.0, 20.0], [9.95, 0.0]])
    assert [choose_victim(xy, docks, w) for w in ("station", "approach", "hall")] == [4, 2, 3]
    assert choose_victim(xy, docks, "station", exclude=(4,)) == 1
    argv = ["--output", str(tmp_path / "x"), "--sizes", "5", "--no-ablations",
            "--fault-size", "5", "--fault-spec", "kill-robot:@station@3",
            "--fault-spec", "kill-robot:@hall@3,kill-nav:@hall@2+2"]
    plan = validate(build_parser().parse_args(argv)).plan
    cells = {c.label: c for c in plan.cells()}
    poi = poi_for_world(resolve_world(plan.world))
    w = poi.workstations[2]
    track = [[[w.pose[0] + 3.0, w.pose[1]]] * 5] * 3
    track[2] = [[-30.0, -30.0], [w.pose[0] + 0.02, w.pose[1]], [w.pose[0], w.pose[1] + 2.0],
                [40.0, 40.0], [w.pose[0] + 0.3, w.pose[1]]]  # at 3 s
    base = run_dir_of(tmp_path, "decentralized-n5", 0, 5)
    base.mkdir(parents=True)
    (base / "sim_summary.json").write_text(json.dumps({"track": {"period_s": 1.0,
                                                                 "xy": track}}))
    assert fault_for(tmp_path, cells["decentralized-n5-f1"], 0, plan.world) == \
        "kill-robot:Srobot2@3"
    # the farthest from every dock at 3 s is (40, 40), robot 4, then (-30, -30) at 2 s
    assert fault_for(tmp_path, cells["decentralized-n5-f2"], 0, plan.world) == \
        "kill-robot:Srobot4@3,kill-nav:Srobot1@2+2"
    with pytest.raises(InputError, match="seed 1 of this experiment.*run it first"):
        fault_for(tmp_path, cells["decentralized-n5-f1"], 1, plan.world)
    assert variant_args(tmp_path, cells["decentralized-n5-f1"], "kill-robot:Srobot2@3") == (
        "--faults", "kill-robot:Srobot2@3")


def test_the_no_fault_record_keeps_the_victims_place_for_a_later_sitting(tmp_path, monkeypatch):
    """A sweep sliced across sittings: the no-fault run at the fault size keeps the robots'
    positions at the placed fault's time in its record, so the fault run of a later sitting is
    placed with its run directory gone; the N-1 run and the fault run keep none."""
    import shutil

    import swarm_bench.bench as bench
    from swarm_bench import experiment
    from swarm_scene.poi import poi_for_world
    from swarm_scene.world import resolve_world

    ran = []
    out = tmp_path / "x"
    base = ["--variants", "decentralized", "--sizes", "5", "--runs", "1", "--no-ablations",
            "--fault-size", "5", "--fault-spec", "kill-robot:@station@3", "--fault-n-minus-1"]
    w = poi_for_world(resolve_world("slim_blockage")).workstations[0]
    far = [w.pose[0] + 3.0, w.pose[1]]

    def fake_run(bcfg, n, r, stop, view):
        ran.append((n, bcfg.extra_args))
        run = bcfg.run_dir / f"n{n}-r{r}"
        run.mkdir(parents=True, exist_ok=True)
        at_3s = [far] * n
        at_3s[3] = [w.pose[0] + 0.05, w.pose[1]]  # robot 4 docked at 3 s
        (run / "sim_summary.json").write_text(json.dumps(
            {"track": {"period_s": 1.0, "xy": [[far] * n, [far] * n, at_3s]}}))
        return {**fake_record("?", "?", bcfg.coordination, n, bcfg.seed, 2.0),
                "interrupted": False}

    monkeypatch.setattr(bench, "run_swarm_up", fake_run)
    argv = ["--output", str(out), *base, "--only", "main"]
    assert experiment.experiment(validate(build_parser().parse_args(argv)), argv) == 0
    kept = json.loads(record_path(out, "decentralized-n5", 0).read_text())["victim_positions"]
    assert list(kept) == ["3"] and kept["3"][3] == [w.pose[0] + 0.05, w.pose[1]]
    shutil.rmtree(out / "runs")  # the next sitting: records only
    argv = ["--resume", str(out), *base, "--only", "fault"]
    assert experiment.experiment(validate(build_parser().parse_args(argv)), argv) == 0
    assert ran[1:] == [(4, ()), (5, ("--faults", "kill-robot:Srobot4@3"))]
    hit = json.loads(record_path(out, "decentralized-n5-f1", 0).read_text())
    fewer = json.loads(record_path(out, "decentralized-n4", 0).read_text())
    assert hit["fault_resolved"] == "kill-robot:Srobot4@3"
    assert "victim_positions" not in hit and "victim_positions" not in fewer


def test_factorial_effects_by_hand():
    from swarm_bench.experiment_stats import factorial_2x2

    # y(a, b) = 10 + 4a + 2b + 3ab, plus a seed offset that the pairing removes
    y = {(a, b): {s: 10 + 4 * a + 2 * b + 3 * a * b + s for s in range(5)}
         for a in (0, 1) for b in (0, 1)}
    eff = factorial_2x2(y)
    assert set(eff["A"].values()) == {4 + 1.5} and set(eff["B"].values()) == {2 + 1.5}
    assert set(eff["AxB"].values()) == {3}
    y[(1, 1)].pop(4)  # a seed missing in one cell is left out of every effect
    assert sorted(factorial_2x2(y)["A"]) == [0, 1, 2, 3]


def test_the_ablations_are_reported_as_a_factorial_with_no_chain_shares(tmp_path):
    """All the factorial's cells at 20 robots: main effects and interactions of both 2 x 2
    designs and the reservation horizon are tested (in the Holm family) and tabled; the
    chain's shares are not given."""
    from swarm_bench.bench import _write_json
    from swarm_bench.experiment_report import write_report

    ablations = ("decentralized-no-swap,centralized-fifo,centralized-fifo-hall,"
                 "centralized-scheduler-hall,centralized-pipelined-spots")
    argv = ["--output", str(tmp_path / "a"), *TWO_ARMS, "--sizes", "20", "--no-faults",
            "--ablations", ablations, "--ablation-size", "20"]
    plan = validate(build_parser().parse_args(argv)).plan
    out = tmp_path / "a"
    (out / "records").mkdir(parents=True)
    _write_json(out / "plan.json", {"settings": plan.settings()})
    # tasks per 100 s: mode (centralized -1), flexible goal (+0.5), their interaction
    # (+0.25 more for centralized), near spots (+0.2 for centralized), pipelined (+0.4)
    rate = {"decentralized": 3.0, "decentralized-no-swap": 2.5,
            "centralized-scheduler": 2.75, "centralized-fifo": 2.0,
            "centralized-scheduler-hall": 2.55, "centralized-fifo-hall": 1.8,
            "centralized-pipelined-spots": 3.15}
    for cell, seed in plan.runs_in_order():
        _write_json(record_path(out, cell.label, seed),
                    fake_record(cell.label, cell.variant, cell.mode, cell.size, seed,
                                rate[cell.variant] + 0.1 * seed, role=cell.role))
    write_report([out], out)
    doc = json.loads((out / "experiment.json").read_text())
    rows = {(r["a"], r["b"], r["measure"]): r for r in doc["statistics"]
            if r["role"] == "factorial"}
    mode = rows[("mode x goal flexibility", "mode: centralized - decentralized", "throughput")]
    inter = rows[("mode x goal flexibility", "mode x goal interaction", "throughput")]
    # per 100 s x 36 = per hour, up to the fake records' rounding of task counts
    assert mode["diff"] == pytest.approx(-0.375 * 36, abs=3.0) and mode["n"] == 5
    assert inter["diff"] == pytest.approx(0.25 * 36, abs=3.0)
    horizon = next(r for r in doc["statistics"] if r["role"] == "factorial" and r["what"])
    assert (horizon["a"], horizon["b"]) == ("centralized-scheduler-n20",
                                            "centralized-pipelined-spots-n20")
    assert all(r["p_holm"] is None or r["p_holm"] >= r["p_t"] for r in doc["statistics"])
    report = (out / "report.md").read_text()
    assert "### Ablations as a factorial" in report
    assert "adds up to the whole gap" not in report


def test_every_variant_has_a_style():
    from swarm_bench.experiment_report import STYLE

    assert set(STYLE) == set(VARIANTS)


def test_equivalence_and_cumulative_loss_by_hand():
    from swarm_bench.experiment_stats import cumulative_lost, equivalence

    # differences near 0 and tight: within a margin of 2; a margin of 0.1 is too narrow
    diffs = [0.5, -0.5, 0.2, -0.1, 0.1]
    assert equivalence(diffs, 2.0)["equivalent"] is True
    assert equivalence(diffs, 2.0)["p_equiv"] < 0.05
    assert equivalence(diffs, 0.1)["equivalent"] is False
    assert equivalence([1.0], 2.0)["p_equiv"] is None
    base = [100.0, 110.0, 125.0, 140.0, 170.0]
    hit = [100.0, 125.0, 170.0]
    # fault at 100 s, 30 s steps to 190 s: by 130 s base 3 (100, 110, 125) hit 2 (100, 125)
    assert cumulative_lost(base, hit, 100.0, 190.0) == [1.0, 2.0, 2.0]


def test_the_fault_study_runs_more_seeds_and_an_n_minus_1_cell(tmp_path):
    argv = ["--output", str(tmp_path / "x"), *TWO_ARMS, "--sizes", "20", "--no-ablations",
            "--fault-size", "20", "--fault-spec", "kill-robot:@approach@360",
            "--fault-runs", "10", "--fault-n-minus-1"]
    plan = validate(build_parser().parse_args(argv)).plan
    seeds = {}
    for cell, seed in plan.runs_in_order():
        seeds.setdefault(cell.label, []).append(seed)
    # the fault study's cells (the faults, their no-fault runs, the N-1 runs) have 10 seeds
    assert {k: len(v) for k, v in seeds.items()} == {
        "decentralized-n20": 10, "centralized-scheduler-n20": 10,
        "decentralized-n19": 10, "centralized-scheduler-n19": 10,
        "decentralized-n20-f1": 10, "centralized-scheduler-n20-f1": 10}
    assert plan_from_settings(plan.settings()) == plan
    plain = validate(build_parser().parse_args(
        ["--output", str(tmp_path / "y"), "--no-faults"])).plan
    assert "fault_runs" not in plain.settings() and "fault_n_minus_1" not in plain.settings()


def test_the_fault_report_compares_with_n_minus_1_and_tests_equivalence(tmp_path):
    from swarm_bench.bench import _write_json
    from swarm_bench.experiment_report import write_report

    argv = ["--output", str(tmp_path / "a"), "--sizes", "20", "--no-ablations",
            "--fault-size", "20", "--fault-spec", "kill-robot:3@360", "--fault-n-minus-1",
            "--variants", "decentralized"]
    plan = validate(build_parser().parse_args(argv)).plan
    out = tmp_path / "a"
    (out / "records").mkdir(parents=True)
    _write_json(out / "plan.json", {"settings": plan.settings()})
    rate = {"decentralized-n20": 3.0, "decentralized-n19": 2.9, "decentralized-n20-f1": 3.0}
    for cell, seed in plan.runs_in_order():
        _write_json(record_path(out, cell.label, seed),
                    fake_record(cell.label, cell.variant, cell.mode, cell.size, seed,
                                rate[cell.label] + 0.01 * seed
                                + (0.12 * (seed % 3) if cell.fault else 0.0),
                                role=cell.role, fault=cell.fault))
    write_report([out], out)
    doc = json.loads((out / "experiment.json").read_text())
    rows = [r for r in doc["statistics"] if r["role"] == "fault"]
    assert [(r["a"], r["b"]) for r in rows] == [
        ("decentralized-n20", "decentralized-n20-f1"),
        ("decentralized-n19", "decentralized-n20-f1")]
    assert rows[0]["margin"] > 0 and "p_equiv" in rows[0]
    assert rows[1]["what"] == "kill-robot:3@360, against 19 robots" and rows[1]["diff"] < 0
    report = (out / "report.md").read_text()
    assert "against a margin of ±" in report and "![tasks lost 1](fault_lost_1.png)" in report


def test_the_report_says_when_the_coordinator_noticed_the_victim(tmp_path):
    """``coordinator_lapses`` of a centralized fault run: the victim's first lapse at or after
    the kill, in simulated seconds after it (another robot's lapse, and the victim's before
    the kill, do not count); a victim never noticed says so; decentralized runs say nothing."""
    from swarm_bench.bench import _write_json
    from swarm_bench.experiment_report import detections, write_report

    argv = ["--output", str(tmp_path / "a"), "--sizes", "20", "--no-ablations",
            "--fault-size", "20", "--fault-spec", "kill-robot:@approach@360",
            "--variants", "decentralized,centralized-pipelined", "--runs", "2"]
    plan = validate(build_parser().parse_args(argv)).plan
    out = tmp_path / "a"
    (out / "records").mkdir(parents=True)
    _write_json(out / "plan.json", {"settings": plan.settings()})
    lapses = {0: [{"robot": "Srobot5", "t_s": 100.0, "workstation": "L1", "reason": "lease"},
                  {"robot": "Srobot9", "t_s": 200.0, "workstation": "L2", "reason": "lease"},
                  {"robot": "Srobot5", "t_s": 661.5, "workstation": "L1", "reason": "lease"}],
              1: []}
    for cell, seed in plan.runs_in_order():
        rec = fake_record(cell.label, cell.variant, cell.mode, cell.size, seed, 3.0,
                          role=cell.role, fault=cell.fault)
        if cell.fault:
            rec["fault_resolved"] = f"kill-robot:Srobot{5 + seed}@360"
            if cell.mode == "centralized":
                rec["metrics"]["coordinator_lapses"] = lapses[seed]
        _write_json(record_path(out, cell.label, seed), rec)
    write_report([out], out)
    doc = json.loads((out / "experiment.json").read_text())
    assert detections("centralized-pipelined-n20-f1", doc["records"]) == [
        (0, "Srobot5: 301.5 s (lease)"), (1, "Srobot6: not within the run")]
    assert detections("decentralized-n20-f1", doc["records"]) == []
    report = (out / "report.md").read_text()
    assert ("the coordinator noticed the victim (its `coordinator_lapses`, after the fault): "
            "seed 0 Srobot5: 301.5 s (lease); seed 1 Srobot6: not within the run") in report
