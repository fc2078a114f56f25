"""``--robot`` as one model or a mix: parsing, the fleet file, interleaving, descriptions."""

from __future__ import annotations

from collections import Counter

import pytest

from swarm_common.errors import InputError
from swarm_scene.fleet import (
    describe_fleet,
    fleet_counts,
    fleet_models,
    fleet_total,
    format_fleet,
    interleave,
    model_label,
    parse_fleet,
)

MIX = "turtlebot3_waffle:12,turtlebot3_burger:4,linorobot2_2wd:4"


# -- parsing -----------------------------------------------------------------------------------


@pytest.mark.parametrize("text, entries", [
    ("turtlebot3_waffle", (("turtlebot3_waffle", None),)),
    ("  robots/x.urdf ", (("robots/x.urdf", None),)),
    ("turtlebot3_burger:3", (("turtlebot3_burger", 3),)),
    (MIX, (("turtlebot3_waffle", 12), ("turtlebot3_burger", 4), ("linorobot2_2wd", 4))),
    (" a : 2 , b:1 ", (("a", 2), ("b", 1))),
    ("/tmp/my robot.urdf:2,b:1", (("/tmp/my robot.urdf", 2), ("b", 1))),
])
def test_parse_good(text, entries):
    assert parse_fleet(text) == entries
    # and back: the text the simulator is given parses to the same entries
    assert parse_fleet(format_fleet(entries)) == entries


@pytest.mark.parametrize("text, message", [
    ("", "empty; expected NAME|PATH or NAME:COUNT,NAME:COUNT,..."),
    ("a:2,,b:1", "empty entry in 'a:2,,b:1'; expected NAME:COUNT,NAME:COUNT,..."),
    ("a:2,b", "'b': a mix needs NAME:COUNT for every model"),
    (":3", "':3': a mix needs NAME:COUNT for every model"),
    ("a:0,b:1", "'a:0': the count must be a positive integer, got '0'"),
    ("a:-2,b:1", "'a:-2': the count must be a positive integer, got '-2'"),
    ("a:two", "'a:two': the count must be a positive integer, got 'two'"),
    ("a:1.5,b:1", "'a:1.5': the count must be a positive integer, got '1.5'"),
    ("a:1,b:2,a:3", "'a' is listed twice; give each model once with its count"),
])
def test_parse_bad_is_one_line_naming_the_entry(text, message):
    with pytest.raises(InputError) as err:
        parse_fleet(text)
    assert str(err.value) == message


def test_counts_must_add_up_to_the_swarm_size():
    assert len(fleet_models(MIX, 20)) == 20
    with pytest.raises(InputError) as err:
        fleet_models(MIX, 19)
    assert str(err.value) == f"the counts of '{MIX}' add up to 20, not to --swarm-size 19"
    assert fleet_total(MIX) == 20 and fleet_total("turtlebot3_waffle") is None


def test_one_model_is_every_robot():
    assert fleet_models("turtlebot3_burger", 3) == ("turtlebot3_burger",) * 3
    assert fleet_models("turtlebot3_burger:3", 3) == ("turtlebot3_burger",) * 3


# -- the fleet file ----------------------------------------------------------------------------


def test_fleet_file_gives_the_same_fleet_as_the_inline_mix(tmp_path):
    (tmp_path / "robots").mkdir()
    (tmp_path / "robots" / "mine.urdf").write_text("<robot/>")
    path = tmp_path / "fleet.yaml"
    path.write_text("fleet:\n"
                    "  - {robot: turtlebot3_waffle, count: 12}\n"
                    "  - {robot: turtlebot3_burger, count: 4}\n"
                    "  - {robot: robots/mine.urdf, count: 4}\n")
    mine = str((tmp_path / "robots" / "mine.urdf").resolve())
    assert parse_fleet(str(path)) == (("turtlebot3_waffle", 12), ("turtlebot3_burger", 4),
                                      (mine, 4))
    inline = "turtlebot3_waffle:12,turtlebot3_burger:4," + mine + ":4"
    assert fleet_models(str(path), 20) == fleet_models(inline, 20)


@pytest.mark.parametrize("body, message", [
    ("robots:\n  - {robot: a, count: 1}\n", "unknown key 'robots'"),
    ("fleet: []\n", "'fleet' must be a non-empty list of {robot, count}"),
    ("fleet:\n  - {robot: a, cuont: 1}\n", "fleet[0]: unknown key 'cuont' (did you mean "
                                            "'count'?)"),
    ("fleet:\n  - {robot: a}\n", "fleet[0]: missing key 'count'"),
    ("fleet:\n  - {robot: a, count: 0}\n", "fleet[0]: count must be a positive integer, got 0"),
    ("fleet:\n  - {robot: a, count: 1}\n  - {robot: a, count: 2}\n",
     "'a' is listed twice"),
    ("fleet: [\n", "not readable YAML"),
])
def test_fleet_file_is_strict(tmp_path, body, message):
    path = tmp_path / "fleet.yaml"
    path.write_text(body)
    with pytest.raises(InputError) as err:
        parse_fleet(str(path))
    assert str(err.value).startswith(str(path)) and message in str(err.value)
    assert "\n" not in str(err.value)


def test_missing_fleet_file(tmp_path):
    with pytest.raises(InputError, match="no such fleet file"):
        parse_fleet(str(tmp_path / "nope.yml"))


# -- interleaving ------------------------------------------------------------------------------


def test_interleave_worked_examples():
    assert interleave([("a", 3), ("b", 1)]) == ("a", "a", "b", "a")
    assert "".join(interleave([("W", 12), ("B", 4), ("L", 4)])) == "WBWLW" * 4
    assert "".join(interleave([("a", 1), ("b", 1), ("c", 1)])) == "abc"
    # robot 1 is the most numerous model (the first listed of a tie)
    assert interleave([("few", 1), ("many", 9)])[:5] == ("many",) * 4 + ("few",)
    assert interleave([("b", 2), ("a", 2)])[0] == "b"


@pytest.mark.parametrize("counts", [(12, 4, 4), (1, 9), (5, 5), (7, 3, 2, 1), (1, 1, 1, 97),
                                    (33, 34, 33)])
def test_interleave_gives_every_count_spread_evenly(counts):
    entries = [(f"m{j}", c) for j, c in enumerate(counts)]
    out = interleave(entries)
    n = sum(counts)
    assert Counter(out) == {m: c for m, c in entries}
    # after any k robots, each model has its share k * c / n within one robot
    placed = Counter()
    for k, model in enumerate(out, start=1):
        placed[model] += 1
        for m, c in entries:
            assert abs(placed[m] - k * c / n) < 1.0, (k, m, placed[m])
    assert interleave(entries) == out  # deterministic


# -- descriptions ------------------------------------------------------------------------------


def test_labels_and_descriptions():
    assert model_label("turtlebot3_burger") == "turtlebot3_burger"
    assert model_label("/x/y/my_bot.urdf.xacro") == "my_bot"
    assert model_label("/x/y/other.urdf") == "other"
    models = fleet_models(MIX, 20)
    assert fleet_counts(models) == {"turtlebot3_waffle": 12, "turtlebot3_burger": 4,
                                    "linorobot2_2wd": 4}
    assert list(fleet_counts(models)) == ["turtlebot3_waffle", "turtlebot3_burger",
                                          "linorobot2_2wd"]
    assert describe_fleet(models) == ("20 (12 turtlebot3_waffle, 4 turtlebot3_burger, "
                                      "4 linorobot2_2wd)")
    assert describe_fleet(("turtlebot3_waffle",) * 5) == "5"
