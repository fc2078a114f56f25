"""The simulator summary record: file text, round trips, missing/extra keys, malformed files."""

import json
import re
from pathlib import Path

import pytest

from swarm_common.sim_summary import CollisionCounts, RobotSummary, SimSummary, SimSummaryError

RECORD = SimSummary(
    robots=2, ticks=3000, sim_time_s=300.0, wall_time_s=41.25, rtf=7.273,
    robot_ticks_per_s=145.5, late_ticks=1, dropped_messages=0,
    collisions=CollisionCounts(robot_robot=0, robot_wall=2), min_separation_m=0.1234,
    per_robot={"Srobot1": RobotSummary(distance_m=41.5, collisions=2, late_ticks=1),
               "Srobot2": RobotSummary(distance_m=0.0, collisions=0, late_ticks=0)})

# What swarm-sim wrote before the record existed (a dict, json.dumps(indent=2) + "\n").
TEXT = """{
  "robots": 2,
  "ticks": 3000,
  "sim_time_s": 300.0,
  "wall_time_s": 41.25,
  "rtf": 7.273,
  "robot_ticks_per_s": 145.5,
  "late_ticks": 1,
  "dropped_messages": 0,
  "collisions": {
    "robot_robot": 0,
    "robot_wall": 2
  },
  "min_separation_m": 0.1234,
  "per_robot": {
    "Srobot1": {
      "distance_m": 41.5,
      "collisions": 2,
      "late_ticks": 1
    },
    "Srobot2": {
      "distance_m": 0.0,
      "collisions": 0,
      "late_ticks": 0
    }
  }
}
"""


def test_file_text_is_the_simulators_format(tmp_path: Path):
    assert RECORD.to_json() == TEXT
    path = tmp_path / "sim_summary.json"
    RECORD.write(path)
    assert path.read_text() == TEXT


def test_round_trips(tmp_path: Path):
    assert SimSummary.from_json(TEXT) == RECORD
    assert SimSummary.from_dict(RECORD.to_dict()) == RECORD
    RECORD.write(tmp_path / "s.json")
    assert SimSummary.read(tmp_path / "s.json") == RECORD
    assert SimSummary.from_json(SimSummary().to_json()) == SimSummary()


def test_numbers_are_kept_as_written():
    text = json.dumps({"sim_time_s": 10, "min_separation_m": 0.5,
                       "per_robot": {"a": {"distance_m": 3}}})
    summary = SimSummary.from_json(text)
    assert summary.sim_time_s == 10 and isinstance(summary.sim_time_s, int)
    assert summary.robot("a").distance_m == 3
    assert json.loads(summary.to_json()) == {**json.loads(SimSummary().to_json()),
                                             **json.loads(text),
                                             "per_robot": {"a": {"distance_m": 3,
                                                                 "collisions": None,
                                                                 "late_ticks": None}}}


def test_missing_keys_are_none_and_extra_keys_are_kept():
    summary = SimSummary.from_dict({"ticks": 10, "future_figure": [1, 2],
                                    "collisions": {"robot_wall": 1, "robot_sky": 9},
                                    "per_robot": {"/Srobot1": {"late_ticks": 2, "x": 0}}})
    assert (summary.ticks, summary.sim_time_s, summary.min_separation_m) == (10, None, None)
    assert summary.collisions == CollisionCounts(robot_robot=None, robot_wall=1)
    assert summary.extras == {"future_figure": [1, 2]}
    assert list(summary.to_dict())[-1] == "future_figure"  # written back, after the fields
    # a robot keyed with its leading "/" is found without it; an absent robot has no figures
    assert summary.robot("Srobot1") == RobotSummary(late_ticks=2)
    assert summary.robot("Srobot9") == RobotSummary()
    assert SimSummary.from_dict({}) == SimSummary()


@pytest.mark.parametrize(("text", "message"), [
    ("{not json", "not JSON"),
    ("[1, 2]", "expected a JSON object, got list"),
    ('{"ticks": "12"}', "ticks: expected an integer, got '12'"),
    ('{"ticks": 12.0}', "ticks: expected an integer, got 12.0"),
    ('{"late_ticks": true}', "late_ticks: expected an integer, got True"),
    ('{"sim_time_s": NaN}', "sim_time_s: expected a finite number, got nan"),
    ('{"collisions": 3}', "collisions: expected an object, got 3"),
    ('{"collisions": {"robot_robot": "x"}}', "collisions.robot_robot: expected an integer"),
    ('{"per_robot": {"Srobot1": {"distance_m": "far"}}}',
     "per_robot.Srobot1.distance_m: expected a finite number, got 'far'"),
    ('{"per_robot": [1]}', "per_robot: expected an object, got [1]"),
])
def test_malformed_summary_is_a_clear_error(tmp_path: Path, text, message):
    with pytest.raises(SimSummaryError, match="^" + re.escape(message)):
        SimSummary.from_json(text)
    path = tmp_path / "sim_summary.json"
    path.write_text(text)
    with pytest.raises(SimSummaryError) as info:
        SimSummary.read(path)
    assert str(info.value).startswith(f"{path}: {message}")


def test_missing_file_is_file_not_found(tmp_path: Path):
    with pytest.raises(FileNotFoundError):
        SimSummary.read(tmp_path / "nothing.json")
