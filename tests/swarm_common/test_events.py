"""The ``/swarm/events`` records (swarm_common/events.py): one encoding, read back by every
reader."""

import pytest

from swarm_common.coordination import (
    EVENT_COORDINATOR,
    EVENT_LAPSE,
    EVENT_RESERVATION,
    EVENT_TASK,
)
from swarm_common.events import (
    COLLISION,
    KINDS,
    LATE,
    ROBOT_ROBOT,
    SPAWN,
    CollisionEvent,
    LateEvent,
    RobotNotice,
    SpawnEvent,
    decode_robot_event,
)
from swarm_common.faults import EVENT_NAME


@pytest.mark.parametrize("event", [
    SpawnEvent("Srobot1", 1.2345, -2.0, 0.0, yaw=1.5708),
    CollisionEvent("Srobot2", 3.0, 4.0, 12.3, other="Srobot7", kind=ROBOT_ROBOT),
    CollisionEvent("Srobot2", 3.0, 4.0, 12.3, other="wall_3"),
    LateEvent("Srobot3", 0.0, 0.0, 99.9),
    RobotNotice("Srobot4", 5.5, 6.5, 7.5),
])
def test_a_record_reads_back_from_its_values_at_the_written_precision(event):
    values = event.encode()
    assert all(isinstance(v, str) for v in values.values())
    back = type(event).decode(values)
    assert back.robot == event.robot
    assert back.x == pytest.approx(event.x, abs=5e-4) and back.t == pytest.approx(event.t)
    assert type(event).decode(back.encode()) == back  # stable once written


def test_the_wire_format_is_the_one_the_readers_have_always_read():
    values = CollisionEvent("Srobot2", 3.0, 4.0, 12.3, other="Srobot7",
                            kind=ROBOT_ROBOT).encode()
    assert values == {"robot": "Srobot2", "x": "3.000", "y": "4.000", "t": "12.300",
                      "other": "Srobot7", "kind": "robot_robot"}
    assert list(SpawnEvent("Srobot1", 1.0, 2.0, 0.0, 0.5).encode()) == [
        "robot", "x", "y", "t", "yaw"]


@pytest.mark.parametrize("values", [
    {"x": "1", "y": "2", "t": "3"},  # no robot
    {"robot": "Srobot1", "x": "nan?", "y": "2", "t": "3"},
    {"robot": "Srobot1", "y": "2", "t": "3"},
])
def test_a_malformed_status_decodes_to_none(values):
    assert LateEvent.decode(values) is None


def test_a_lenient_reader_counts_an_event_without_position():
    ev = CollisionEvent.decode({"robot": "/Srobot2", "other": "wall"}, lenient=True)
    assert (ev.robot, ev.other, ev.x, ev.y, ev.t) == ("Srobot2", "wall", 0.0, 0.0, 0.0)
    assert CollisionEvent.decode({"other": "wall"}, lenient=True) is None


def test_decode_robot_event_dispatches_by_kind_and_strips_the_leading_slash():
    ev = decode_robot_event(COLLISION, {"robot": "/Srobot1", "x": "0", "y": "0", "t": "1",
                                        "other": "/Srobot2", "kind": ROBOT_ROBOT})
    assert isinstance(ev, CollisionEvent) and (ev.robot, ev.other) == ("Srobot1", "Srobot2")
    assert isinstance(decode_robot_event(SPAWN, {"robot": "a", "x": "0", "y": "0", "t": "0"}),
                      SpawnEvent)
    assert isinstance(decode_robot_event(LATE, {"robot": "a", "x": "0", "y": "0", "t": "0"}),
                      LateEvent)
    assert decode_robot_event(EVENT_TASK, {"robot": "a"}) is None


def test_every_kind_is_listed_once():
    assert len(set(KINDS)) == len(KINDS)
    assert {SPAWN, COLLISION, LATE, EVENT_NAME, EVENT_RESERVATION, EVENT_TASK,
            EVENT_COORDINATOR, EVENT_LAPSE} == set(KINDS)
