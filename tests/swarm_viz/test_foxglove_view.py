"""The Foxglove view without ROS: a goal's JSON, and what clients' subscriptions ask of the
live view (nothing while nobody subscribes; the scans of the robots whose scan is watched)."""

from __future__ import annotations

import json
import math
import threading

import numpy as np
import pytest

from swarm_viz.fleet_view import FleetState
from swarm_viz.foxglove_view import FoxgloveView, goal_from_json


def test_a_goal_as_foxgloves_publish_panel_sends_it():
    msg = {"header": {"frame_id": "map", "stamp": {"sec": 0, "nanosec": 0}},
           "pose": {"position": {"x": 1.5, "y": -2.0, "z": 0.0},
                    "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(0.4), "w": math.cos(0.4)}}}
    x, y, yaw, frame = goal_from_json(json.dumps(msg).encode())
    assert (x, y, frame) == (1.5, -2.0, "map") and yaw == pytest.approx(0.8)


@pytest.mark.parametrize("data", [b"not json", b"{}", b'{"pose": {"position": {"x": 1}}}',
                                  b'{"pose": {"position": {"x": "nan", "y": 0}}}'])
def test_a_malformed_goal_is_refused(data):
    with pytest.raises(ValueError, match="goal|PoseStamped"):
        goal_from_json(data)


class _Channel:
    def __init__(self, cid):
        self.cid = cid

    def id(self):
        return self.cid


def _view(calls):
    fleet = FleetState(("Srobot1", "Srobot2"))
    view = FoxgloveView(
        fleet=fleet, fleet_lock=threading.Lock(), recorder=None, recorder_lock=threading.Lock(),
        occ=None, workstations=(), footprint=np.zeros((4, 2)), lidar_pose=(0.0, 0.0, 0.0),
        ws_states=lambda: ([], []), on_demand=lambda n: calls.append(("demand", n)),
        on_watch=lambda w: calls.append(("watch", w)),
        on_goal=lambda *goal: calls.append(("goal", goal)), port=0)
    view.ch_map = _Channel(1)
    view._scan_index = {10: 0, 11: 1}  # the robots' scan channels
    return view


def test_subscriptions_drive_the_live_views_demand_and_scans():
    calls = []
    view = _view(calls)
    assert calls == [] and not any(view._subs.values())  # no client: nothing asked for
    view._subscribed(client=7, channel=11, on=True)
    assert calls[-2:] == [("demand", 1), ("watch", frozenset({1}))]
    view._subscribed(client=8, channel=1, on=True)
    assert calls[-2] == ("demand", 2) and view._map_pending  # the map again for the new client
    view._subscribed(client=7, channel=11, on=False)
    view._subscribed(client=8, channel=1, on=False)
    assert calls[-2:] == [("demand", 0), ("watch", frozenset())]


def test_a_goal_on_a_robots_goal_pose_channel_is_handed_on():
    calls = []
    view = _view(calls)
    view._advertised(3, 1, "/Srobot2/goal_pose", "json", "geometry_msgs/msg/PoseStamped")
    view._advertised(3, 2, "/Srobot9/goal_pose", "json", "geometry_msgs/msg/PoseStamped")
    goal = json.dumps({"pose": {"position": {"x": 1.0, "y": 2.0}}}).encode()
    view._message(3, 1, goal)
    view._message(3, 2, goal)  # no such robot: not advertised
    view._message(3, 1, b"{")  # malformed: counted, dropped
    assert calls == [("goal", ("Srobot2", 1.0, 2.0, 0.0, "map"))]
    assert (view.goals_published, view.malformed_goals) == (1, 1)


def test_the_layout_file_shows_only_what_the_server_serves():
    """docs/foxglove_layout.json: every topic and field its panels name is a channel of a
    running server (on a free port, no ROS) and a field of that channel's schema."""
    from swarm_common.paths import ROOT
    from swarm_viz.foxglove_view import KPI_SCHEMA, NAV_STATUS_SCHEMA

    layout = json.loads((ROOT / "docs" / "foxglove_layout.json").read_text())
    panels = layout["configById"]
    used = set(panels["3D!swarm"]["topics"])
    paths = [p["value"] for p in panels["Plot!tasks"]["paths"]]
    paths += [p["value"] for p in panels["StateTransitions!robot"]["paths"]]
    used |= {p.split(".")[0] for p in paths}
    used |= {panels["RawMessages!status"]["topicPath"], panels["Log!collisions"]["topicToRender"]}
    view = _view([])
    view.workstations = ()
    view.start()
    try:
        served = {c.topic() for c in (view.ch_map, view.ch_tf, view.ch_poses, view.ch_footprints,
                                      view.ch_plans, view.ch_ws, view.ch_events, view.ch_log,
                                      view.ch_kpi, *view.ch_scans, *view.ch_status)}
        assert view.port > 0
    finally:
        view.stop()
    assert used <= served, used - served
    fields = {"/swarm/kpi": KPI_SCHEMA[1]["properties"],
              "/Srobot1/nav_status": NAV_STATUS_SCHEMA[1]["properties"]}
    for path in paths:
        topic, field = path.split(".", 1)
        assert field in fields[topic], path


def _client_can_parse(schema: dict, where: str) -> None:
    """The rules of the clients' JSON Schema reader (parseJsonSchema, @foxglove/mcap-support, as in
    Foxglove Studio 1.48): an object has "properties"; every field has one type (a string, not a
    list); an array has "items" of one type."""
    assert schema.get("type") == "object" and isinstance(schema.get("properties"), dict), where
    for name, field in schema["properties"].items():
        assert isinstance(field.get("type"), str), f"{where}.{name}"
        if field["type"] == "object":
            _client_can_parse(field, f"{where}.{name}")
        if field["type"] == "array":
            assert isinstance(field.get("items", {}).get("type"), str), f"{where}.{name}"


def test_json_schemas_are_ones_the_clients_read():
    """A schema a client refuses loses its channel there ("schema:/swarm/kpi" in Foxglove
    Studio 1.48: a list of types)."""
    from swarm_viz.foxglove_view import KPI_SCHEMA, NAV_STATUS_SCHEMA

    for name, schema in (KPI_SCHEMA, NAV_STATUS_SCHEMA):
        _client_can_parse(schema, name)
