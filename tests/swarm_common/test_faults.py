"""The ``--faults`` syntax, its YAML form and the event/ack records (swarm_common.faults)."""

import math

import pytest

from swarm_common.errors import InputError
from swarm_common.faults import (
    DEFAULT_NAV_OUTAGE_S,
    Fault,
    FaultAck,
    FaultEvent,
    drop_rng,
    dump_faults,
    parse_faults,
)

ROBOTS = tuple(f"Srobot{i}" for i in range(1, 6))


def test_every_kind_parses_to_its_fields():
    faults = parse_faults("kill-nav:3@60,kill-robot:Srobot4@90.5,freeze:2@30+20,"
                          "drop:2/scan:50%@30s+20s,kill-coordinator@120+10,"
                          "kill-coordinator@200,drop:/Srobot1/cmd_vel:0.25@5", ROBOTS)
    assert faults == (
        Fault(1, "kill-nav", 60.0, DEFAULT_NAV_OUTAGE_S, "Srobot3"),
        Fault(2, "kill-robot", 90.5, None, "Srobot4"),
        Fault(3, "freeze", 30.0, 20.0, "Srobot2"),
        Fault(4, "drop", 30.0, 20.0, "Srobot2", "scan", 0.5),
        Fault(5, "kill-coordinator", 120.0, 10.0),
        Fault(6, "kill-coordinator", 200.0, None),
        Fault(7, "drop", 5.0, None, "Srobot1", "cmd_vel", 0.25),
    )
    assert faults[0].at_ns == 60_000_000_000 and faults[0].end_ns == 62_000_000_000
    assert faults[5].end_ns is None
    assert [f.label() for f in faults[:4]] == [
        "kill-nav:Srobot3@60+2", "kill-robot:Srobot4@90.5", "freeze:Srobot2@30+20",
        "drop:Srobot2/scan:0.5@30+20"]


def test_labels_parse_back_to_the_same_faults():
    faults = parse_faults("kill-nav:3@60+5,freeze:2@30,drop:5/odom:0.1@1+2", ROBOTS)
    again = parse_faults(",".join(f.label() for f in faults), ROBOTS)
    assert again == faults


def test_yaml_file_round_trips(tmp_path):
    faults = parse_faults("kill-robot:3@60,drop:2/scan:0.5@30+20,kill-coordinator@100+5",
                          ROBOTS)
    path = tmp_path / "faults.yaml"
    dump_faults(faults, path)
    assert parse_faults(str(path), ROBOTS) == faults
    hand = tmp_path / "hand.yml"
    hand.write_text("faults:\n  - {kind: freeze, robot: 2, at: 30, for: 20}\n"
                    "  - {kind: drop, robot: Srobot1, topic: odom, fraction: 10%, at: 5}\n")
    assert parse_faults(str(hand), ROBOTS) == (
        Fault(1, "freeze", 30.0, 20.0, "Srobot2"), Fault(2, "drop", 5.0, None, "Srobot1",
                                                         "odom", 0.1))


BAD = [
    ("", "empty fault list"),
    ("kill-robot:3", "is not KIND[:TARGET]@TIME[+DURATION]"),
    ("explode:3@60", "unknown fault kind 'explode'"),
    ("kil-robot:3@60", "did you mean 'kill-robot'"),
    ("kill-robot:9@60", "no robot '9'"),
    ("kill-robot:Xrobot1@60", "no robot 'Xrobot1'"),
    ("kill-robot@60", "kill-robot needs a robot"),
    ("kill-robot:3@abc", "the time must be a number"),
    ("kill-robot:3@0", "the time must be > 0 s"),
    ("kill-robot:3@-5", "the time must be a finite number of seconds >= 0"),
    ("kill-robot:3@nan", "the time must be a finite number"),
    ("kill-robot:3@60+10", "kill-robot is for good"),
    ("freeze:2@30+0", "the duration must be > 0 s"),
    ("drop:2/scan@30", "drop needs a fraction"),
    ("drop:2/scna:0.5@30", "did you mean 'scan'"),
    ("drop:2/scan:1.5@30", "the fraction must be in (0, 1]"),
    ("drop:2/scan:0@30", "the fraction must be in (0, 1]"),
    ("drop:2/scan:half@30", "the fraction must be a number"),
    ("kill-coordinator:3@60", "kill-coordinator takes no robot"),
    ("kill-robot:3@60,freeze:3@70+5", "Srobot3 is dead from t = 60 s"),
    ("kill-robot:3@60,kill-robot:3@70", "is already dead"),
    ("kill-nav:3@60+10,kill-nav:3@65", "navigator is still down"),
    ("kill-coordinator@60,kill-coordinator@100", "the coordinator is still down"),
    ("kill-robot:3@400", "starts at or after the end of the run (--duration 300)"),
]


@pytest.mark.parametrize(("spec", "words"), BAD, ids=[b[0] or "empty" for b in BAD])
def test_bad_specs_raise_one_line_naming_the_problem(spec, words):
    with pytest.raises(InputError) as info:
        parse_faults(spec, ROBOTS, duration=300.0)
    text = str(info.value)
    assert words in text
    assert "\n" not in text


def test_bad_yaml_files_name_the_file_and_the_entry(tmp_path):
    path = tmp_path / "f.yaml"
    path.write_text("faults:\n  - {kind: freeze, robot: 2, at: 30, fro: 20}\n")
    with pytest.raises(InputError, match=r"f.yaml: fault 1: unknown key 'fro' \(did you mean "
                                         r"'for'\?\)"):
        parse_faults(str(path), ROBOTS)
    path.write_text("falts: []\n")
    with pytest.raises(InputError, match="unknown key 'falts'"):
        parse_faults(str(path), ROBOTS)
    path.write_text("faults:\n  - {robot: 2, at: 30}\n")
    with pytest.raises(InputError, match="fault 1: missing key 'kind'"):
        parse_faults(str(path), ROBOTS)
    with pytest.raises(InputError, match="missing.yaml"):
        parse_faults(str(tmp_path / "missing.yaml"), ROBOTS)


def test_event_and_ack_records_round_trip():
    ev = FaultEvent(fault=4, kind="drop", phase="start", robot="Srobot2", t=30.0,
                    duration=20.0, topic="scan", fraction=0.5)
    values = ev.encode()
    assert values["t"] == "30.000" and values["fraction"] == "0.5"
    assert FaultEvent.decode(values) == ev
    coord = FaultEvent(fault=1, kind="kill-coordinator", phase="end", t=130.0)
    assert FaultEvent.decode(coord.encode()) == coord
    # The simulator's "stopped answering" events are not injected faults.
    assert FaultEvent.decode({"robot": "Srobot1", "x": "0", "y": "0", "t": "3.0"}) is None
    assert FaultEvent.decode({**values, "fault": "x"}) is None
    ack = FaultAck(4, "start", "group_Srobot1")
    assert FaultAck.decode(ack.encode()) == ack
    assert FaultAck.decode({"fault": "4", "phase": "middle"}) is None


def test_drop_draws_depend_on_seed_and_fault_alone():
    f = Fault(3, "drop", 1.0, None, "Srobot1", "scan", 0.5)
    a, b = drop_rng(7, f).random(50), drop_rng(7, f).random(50)
    assert (a == b).all()
    assert not (drop_rng(8, f).random(50) == a).all()
    other = Fault(4, "drop", 1.0, None, "Srobot1", "scan", 0.5)
    assert not (drop_rng(7, other).random(50) == a).all()
    assert math.isclose(float((drop_rng(0, f).random(10000) < 0.5).mean()), 0.5, abs_tol=0.02)
