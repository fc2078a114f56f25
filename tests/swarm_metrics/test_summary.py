"""The summary swarm-up prints: the tasks per window and the per-workstation table (pure)."""

from swarm_metrics.summary import print_summary

STATIONS = [
    {"name": "loader1", "x": 0.0, "y": 0.0, "goals": 12, "visits": 11, "aborted": 1,
     "mean_time_to_goal_s": 41.25, "holding_time_s": 300.0, "mean_wait_s": 25.0},
    {"name": "unused", "x": 9.0, "y": 9.0, "goals": 0, "visits": 0, "aborted": 0,
     "mean_time_to_goal_s": None, "holding_time_s": 0.0, "mean_wait_s": None},
]


def test_summary_shows_tasks_per_window_and_the_workstations(capsys):
    print_summary({"robots": 20, "tasks_per_window": [70, 72, 61, 5], "task_window_s": 600.0,
                   "task_windows_full": 3, "task_window_ratio_min": 0.918,
                   "workstations": STATIONS}, [])
    out = capsys.readouterr().out
    assert "tasks per 600 s window" in out
    assert "70 / 72 / 61 / 5* (min/mean 0.92)" in out
    lines = {line.split()[1]: line for line in out.splitlines()
             if line.startswith("│") and ("loader1" in line or "unused" in line)}
    assert [c.strip() for c in lines["loader1"].split(
        "│")[2:8]] == ["12", "11", "1", "41.2 s", "300.0 s", "25.0 s"]
    assert [c.strip() for c in lines["unused"].split("│")[2:8]] == ["0", "0", "0", "-",
                                                                   "0.0 s", "-"]


def test_summary_without_goals_has_no_workstation_table(capsys):
    print_summary({"robots": 2, "tasks_per_window": [0], "task_window_s": 600.0,
                   "task_windows_full": 0, "task_window_ratio_min": None,
                   "workstations": STATIONS[1:]}, [])
    out = capsys.readouterr().out
    assert "0*" in out and "min/mean" not in out  # one window, cut short by the end
    assert "workstations" not in out


def test_summary_says_where_robots_stood_still(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # one table row on one line
    print_summary({"robots": 3, "standstills": [
        {"robot": "Srobot1", "duration_s": 75.0, "near": "loader1"},
        {"robot": "Srobot1", "duration_s": 300.0, "near": "loader1"},
        {"robot": "Srobot2", "duration_s": 61.5, "near": None}]}, [])
    out = capsys.readouterr().out
    assert "3 times (2 robots), 436 s; near loader1 2, (elsewhere) 1" in out


def test_summary_says_how_the_tasks_spread_over_the_robots(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # one table row on one line
    print_summary({"robots": 100, "tasks_per_robot": {"min": 0, "median": 5.5, "max": 19,
                                                      "without_task": 12}}, [])
    out = capsys.readouterr().out
    assert "0 / 5.5 / 19 (min / median / max), 12 robots without a task" in out
    print_summary({"robots": 2, "tasks_per_robot": {"min": 3, "median": 4.0, "max": 5,
                                                    "without_task": 0}}, [])
    out = capsys.readouterr().out
    assert "3 / 4.0 / 5 (min / median / max)" in out and "without a task" not in out
    print_summary({"robots": 2}, [])
    assert "tasks per robot" not in capsys.readouterr().out


def test_summary_says_the_fleets_mix(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # one table row on one line
    print_summary({"robots": 20, "fleet": {"turtlebot3_waffle": 12, "turtlebot3_burger": 4,
                                           "linorobot2_2wd": 4}}, [])
    (row,) = [ln for ln in capsys.readouterr().out.splitlines() if "│ robots " in ln]
    assert row.split("│")[2].strip() == ("20 (12 turtlebot3_waffle, 4 turtlebot3_burger, "
                                         "4 linorobot2_2wd)")
    print_summary({"robots": 5, "fleet": {"turtlebot3_waffle": 5}}, [])
    (row,) = [ln for ln in capsys.readouterr().out.splitlines() if "│ robots " in ln]
    assert row.split("│")[2].strip() == "5"  # one model: as before


def _row(out: str, name: str) -> str | None:
    rows = [ln for ln in out.splitlines() if ln.startswith(f"│ {name} ")]
    return rows[0].split("│")[2].strip() if rows else None


def test_summary_says_where_the_robots_spawned(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")  # one table row on one line
    spawn = ("in the spawn area of slim_blockage.yaml, x -2.00..0.00 m, y -1.00..-1.00 m, "
             "first at (-2.00, -1.00)")
    print_summary({"robots": 3, "spawn": spawn, "world_skipped": []}, [])
    out = capsys.readouterr().out
    assert _row(out, "spawned") == spawn
    assert "skipped" not in out  # a world that loads whole: no row
    print_summary({"robots": 3}, [])  # no simulator summary
    assert _row(capsys.readouterr().out, "spawned") == "-"


def test_summary_counts_the_world_elements_skipped(capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "200")
    print_summary({"robots": 1, "world_skipped": ["actor 'walker'", "road 'lane'"]}, [])
    assert (_row(capsys.readouterr().out, "world elements skipped")
            == "2: actor 'walker', road 'lane'")
    print_summary({"robots": 1, "world_skipped": [f"actor 'a{i}'" for i in range(5)]}, [])
    assert (_row(capsys.readouterr().out, "world elements skipped")
            == "5: actor 'a0', actor 'a1', actor 'a2' and 2 more (see logs/sim.log)")
