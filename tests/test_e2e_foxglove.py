"""``swarm-up --foxglove``: a Foxglove WebSocket client (tests/support/foxglove_client.py, written
from the protocol, decoding with ``protobuf`` by the schemas the server advertises) sees the run.

1. Channels and schemas as documented; the map's grid is the world's map; the server's clock is
   the simulated time; every robot's transform at a tick is its ground truth at that tick (read
   back from the run's recording with ``rosbags``, not from the server's code).
2. A goal published by the client on ``/Srobot1/goal_pose`` (JSON, as Foxglove's Publish panel
   sends it) drives that robot there: its ``nav_status`` says SUCCEEDED with that goal, and its
   pose ends within the goal tolerance.
"""

from __future__ import annotations

import asyncio
import math
import socket

import pytest
from rosbags.highlevel import AnyReader

from swarm_common.paths import MAPS_DIR, WORLDS_DIR
from swarm_scene.map_io import load_map
from swarm_scene.poi import load_poi
from tests.support.foxglove_client import FoxgloveClient
from tests.test_e2e_swarm_up import EXIT_SLACK_S, READY_TIMEOUT_S, SwarmUp

pytestmark = pytest.mark.e2e

ROBOTS = ("Srobot1", "Srobot2", "Srobot3")
SCHEMAS = {
    "/map": "foxglove.Grid",
    "/tf": "foxglove.FrameTransforms",
    "/swarm/poses": "foxglove.PosesInFrame",
    "/swarm/footprints": "foxglove.SceneUpdate",
    "/swarm/plans": "foxglove.SceneUpdate",
    "/swarm/workstations": "foxglove.SceneUpdate",
    "/swarm/collisions": "foxglove.Event",
    "/swarm/log": "foxglove.Log",
    "/swarm/kpi": "swarm_workbench/Kpi",
    **{f"/{ns}/scan": "foxglove.LaserScan" for ns in ROBOTS},
    **{f"/{ns}/nav_status": "swarm_workbench/NavStatus" for ns in ROBOTS},
}


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _ns(ts) -> int:
    return ts.seconds * 10**9 + ts.nanos


def _yaw(q) -> float:
    return 2.0 * math.atan2(q.z, q.w)


async def _watch(url: str, seconds_of_tf: int) -> FoxgloveClient:
    client = FoxgloveClient(url)
    await client.connect()
    try:
        await client.subscribe(list(client.channels))
        await client.wait_for(lambda: len(client.messages["/tf"]) >= seconds_of_tf
                              and client.messages["/map"] and client.messages["/swarm/kpi"],
                              timeout=120.0)
    finally:
        await client.close()
    return client


def test_a_foxglove_client_sees_the_run(tmp_path):
    port = _free_port()
    args = ["--swarm-size", str(len(ROBOTS)), "--commanders", "--rtf", "2", "--duration", "40",
            "--foxglove", str(port), "--record", "--record-topics", "ground_truth"]
    with SwarmUp(args, tmp_path, "fox") as run:
        url = run.wait_for_stdout(r"foxglove: (ws://127\.0\.0\.1:\d+)", 60.0).group(1)
        assert url == f"ws://127.0.0.1:{port}"
        run.wait_for_stdout(r"navigators ready in", READY_TIMEOUT_S)
        client = asyncio.run(_watch(url, 20))
        assert run.wait(40 + EXIT_SLACK_S) == 0, run.diagnostics()
    assert {t: ch["schemaName"] for t, ch in client.channels.items()} == SCHEMAS
    assert {"clientPublish", "time"} <= set(client.info["capabilities"])
    assert "json" in client.info["supportedEncodings"]
    # the map: the world's grid, cell for cell
    occ = load_map(MAPS_DIR / "slim_blockage.yaml")
    grid = client.messages["/map"][0][1]
    assert (grid.column_count, grid.cell_size.x) == (occ.width, pytest.approx(occ.resolution))
    assert len(grid.data) == occ.width * occ.height
    assert grid.data == (occ.data.astype("int8").astype("uint8")).tobytes()
    # the clock is simulated time, and it runs
    assert client.times and client.times == sorted(client.times) and client.times[-1] > 1e9
    # every robot's transform at a tick is its ground truth at that tick
    truth = {}
    with AnyReader([run.run_dir / "recording.mcap"]) as reader:
        for conn, _t, raw in reader.messages():
            m = reader.deserialize(raw, conn.msgtype)
            stamp = m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
            q = m.pose.pose.orientation
            truth[(conn.topic.split("/")[1], stamp)] = (
                m.pose.pose.position.x, m.pose.pose.position.y, 2 * math.atan2(q.z, q.w))
    compared = 0
    for _log_time, msg in client.messages["/tf"]:
        for tf in msg.transforms:
            if tf.parent_frame_id != "map":
                continue
            ns = tf.child_frame_id.split("/")[0]
            x, y, yaw = truth[(ns, _ns(tf.timestamp))]
            assert tf.child_frame_id == f"{ns}/base_footprint"
            assert (tf.translation.x, tf.translation.y) == (pytest.approx(x, abs=1e-9),
                                                            pytest.approx(y, abs=1e-9))
            assert math.remainder(_yaw(tf.rotation) - yaw, math.tau) == pytest.approx(
                0.0, abs=1e-9)
            compared += 1
    assert compared >= 20 * len(ROBOTS)
    # each robot's state, and the workstations
    for ns in ROBOTS:
        states = {m["state"] for _t, m in client.messages[f"/{ns}/nav_status"]}
        assert states and states <= {"idle", "planning", "driving", "holding", "recovering",
                                     "succeeded", "aborted", "canceled", None}, states
    scene = client.messages["/swarm/workstations"][-1][1]
    workstations = load_poi(WORLDS_DIR / "slim_blockage.yaml").workstations
    assert sorted(e.id for e in scene.entities) == sorted(
        f"workstation/{w.name}" for w in workstations)
    assert all(e.cubes and e.texts for e in scene.entities)
    kpi = client.messages["/swarm/kpi"][-1][1]
    assert kpi["robots"] == len(ROBOTS) and kpi["collisions"] == 0


async def _send_goal(url: str, goal: tuple[float, float]) -> FoxgloveClient:
    client = FoxgloveClient(url)
    await client.connect()
    try:
        await client.subscribe(["/Srobot1/nav_status", "/swarm/poses"])
        await client.advertise(1, "/Srobot1/goal_pose", "geometry_msgs/msg/PoseStamped")
        await client.wait_for(lambda: client.messages["/Srobot1/nav_status"], timeout=60.0)
        await client.publish(1, {"header": {"frame_id": "map"}, "pose": {
            "position": {"x": goal[0], "y": goal[1], "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}})

        def reached():
            return any(m["state"] == "succeeded" and m["goal"] == pytest.approx(goal, abs=1e-3)
                       for _t, m in client.messages["/Srobot1/nav_status"])

        await client.wait_for(reached, timeout=240.0)
        await asyncio.sleep(1.0)  # one more pose
    finally:
        await client.close()
    return client


def test_a_goal_published_from_foxglove_drives_the_robot(tmp_path):
    goal = (1.5, 0.8)
    args = ["--swarm-size", "1", "--rtf", "2", "--duration", "600", "--foxglove",
            str(_free_port())]
    with SwarmUp(args, tmp_path, "goal") as run:
        url = run.wait_for_stdout(r"foxglove: (ws://127\.0\.0\.1:\d+)", 60.0).group(1)
        run.wait_for_stdout(r"navigators ready in", READY_TIMEOUT_S)
        client = asyncio.run(_send_goal(url, goal))
    x, y = client.messages["/swarm/poses"][-1][1].poses[0].position.x, \
        client.messages["/swarm/poses"][-1][1].poses[0].position.y
    assert math.hypot(x - goal[0], y - goal[1]) < 0.25, (x, y)
