"""The waiting measure: time without progress toward a task's workstation, from ground truth."""

import math

import numpy as np
import pytest
import yaml

from swarm_common.sim_summary import SimSummary
from swarm_metrics.aggregate import RunFacts, RunRecorder, aggregate
from swarm_metrics.waiting import DistanceField, geodesic_field, waiting_s


def test_the_geodesic_field_goes_round_a_wall_by_hand():
    free = np.ones((5, 7), bool)
    free[1:4, 3] = False  # a wall in column 3, rows 1 to 3
    f = geodesic_field(free, 1.0, (2, 0))
    assert f[2, 2] == 2.0 and f[0, 1] == pytest.approx(1 + math.sqrt(2))
    assert math.isinf(f[2, 3])  # the wall
    # (2, 4), behind the wall: (1, 1), (0, 2) diagonally, (0, 3) across, (1, 4) diagonally,
    # (2, 4) down
    assert f[2, 4] == pytest.approx(2 + 3 * math.sqrt(2))


def _wall_map():
    occ = np.zeros((20, 40), np.int8)  # 4 m x 2 m at 0.1 m, a wall at x = 2.0 m up to y = 1.5
    occ[0:15, 20] = 100
    return occ


def test_waiting_counts_the_seconds_without_progress_not_a_detour():
    """A robot that stands 2 s, then drives up and round the wall (away from the target as
    the crow flies, but nearer along the free space) waited 2 s."""
    field = DistanceField(_wall_map(), 0.1, (0.0, 0.0))
    track = [[0.5, 0.5], [0.5, 0.5], [0.5, 0.5], [0.6, 0.9], [1.0, 1.4], [1.5, 1.7],
             [2.0, 1.7], [2.5, 1.5], [3.0, 1.0], [3.5, 0.5]]
    d = field((3.5, 0.5), np.asarray(track))
    assert np.all(np.diff(d[2:]) < 0) and d[-1] == 0.0
    assert waiting_s(track, [(1.0, 10.0, (3.5, 0.5))], field) == 2.0
    # only the seconds inside a task count: from 3 s on it made progress all the time
    assert waiting_s(track, [(3.0, 10.0, (3.5, 0.5))], field) == 0.0
    # a robot backing away from its target waits as much as one standing
    back = [[3.0, 1.0], [2.8, 1.1], [2.6, 1.2], [2.9, 1.0], [3.5, 0.5]]
    assert waiting_s(back, [(1.0, 5.0, (3.5, 0.5))], field) == 2.0


def test_metrics_waiting_is_defined_alike_in_both_modes(tmp_path):
    """The same ground truth gives the same waiting whether the task came from a goal reached
    (decentralized: from the goal taking effect) or from the coordinator's task record
    (centralized: from the assignment)."""
    occ = _wall_map()
    (tmp_path / "m.pgm").write_bytes(b"P5\n40 20\n255\n" + bytes(
        (0 if v == 100 else 254) for v in np.flipud(occ).ravel()))
    (tmp_path / "m.yaml").write_text(yaml.safe_dump({
        "image": "m.pgm", "resolution": 0.1, "origin": [0.0, 0.0, 0.0], "negate": 0,
        "occupied_thresh": 0.65, "free_thresh": 0.196}))
    track = [[[0.5, 0.5]], [[0.5, 0.5]], [[0.5, 0.5]], [[0.6, 0.9]], [[1.0, 1.4]],
             [[1.5, 1.7]], [[2.0, 1.7]], [[2.5, 1.5]], [[3.0, 1.0]], [[3.5, 0.5]]]
    sim = SimSummary(sim_time_s=10.0, extras={"track": {"period_s": 1.0, "xy": track}})
    facts = {"world": "w", "seed": 0, "wall_time_s": 1.0, "map_path": str(tmp_path / "m.yaml"),
             "workstations": {"A": (3.5, 0.5)}}
    dec = RunRecorder(("r1",))
    dec.on_status("r1", {"state": "SUCCEEDED", "goal_id": "0.900000000", "stamp": "10.000000000",
                         "navigation_time_s": "9.0", "goal_x": "3.5", "goal_y": "0.5",
                         "goal_yaw": "0.0"}, 1.0)
    cen = RunRecorder(("r1",))
    cen.on_event("task", {"robot": "r1", "t": "10.000000000", "t_start": "1.000000000",
                          "workstation": "A", "duration_s": "9.000", "epoch": "e"})
    m_dec = aggregate(dec, sim, RunFacts(coordination="decentralized", **facts))
    m_cen = aggregate(cen, sim, RunFacts(coordination="centralized", **facts))
    assert m_dec["tasks_completed"] == m_cen["tasks_completed"] == 1
    assert m_dec["waiting_s"] == m_cen["waiting_s"] == 2.0
    assert m_dec["per_robot"]["r1"]["waiting_s"] == 2.0 and m_cen["waiting_per_task_s"] == 2.0
    # without the simulator's track, or a map: unknown, not 0
    m = aggregate(cen, SimSummary(sim_time_s=10.0), RunFacts(coordination="centralized", **facts))
    assert m["waiting_s"] is None and "waiting_s" not in m["per_robot"]["r1"]
