"""The sensors without PyBullet (swarm_sim.sensors): the engine's scans to the last bit, and any
robots' rows of them rendered elsewhere from the same world, fleet, seed and poses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from swarm_scene.world import load_world
from swarm_sim.sensors import SwarmSensors


@pytest.fixture(scope="module")
def slim():
    return load_world("slim_blockage")


def _drive(engine, k):
    n = engine.n
    engine.step(np.full(n, 0.22), 0.6 * np.sin(np.arange(n) + 0.3 * k))


def _same(a, b):
    """Scans (arrays, or lists with None) equal to the last bit (inf and -inf included)."""
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype == np.float32
        np.testing.assert_array_equal(a, b)
        return
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert (x is None) == (y is None)
        if x is not None:
            np.testing.assert_array_equal(x, y)


POSES = [(2.0 + 0.8 * (i % 4), 1.5 + 0.9 * (i // 4), 0.7 * i) for i in range(12)]


@pytest.mark.parametrize("mix", [False, True])
@pytest.mark.parametrize("rows", [[0], [1, 4, 7], list(range(12))])
def test_rows_rendered_elsewhere_are_the_engines_scans(slim, robots, make_engine, mix, rows):
    if mix:  # three models: a 5 Hz, a 10 Hz and another 5 Hz lidar, different outlines
        names = ("turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd")
        models = [robots[names[i % 3]] for i in range(len(POSES))]
    else:
        models = robots["turtlebot3_waffle"]
    engine = make_engine(slim, models, POSES, seed=7)
    away = SwarmSensors(slim, engine.models, seed=7, control_period=engine.config.control_period)
    scanned = 0
    for k in range(12):
        if engine.lidar_due():
            whole = engine.scans()
            part = away.scans(engine.poses.copy(), engine.ticks, rows)
            _same(part, [whole[i] for i in rows] if mix else whole[rows])
            scanned += 1
        _drive(engine, k)
    assert scanned >= 6  # the waffle's lidar every other tick, the burger's every tick
    # the noise goes on alike: another full scan from both
    while not engine.lidar_due():
        _drive(engine, 0)
    _same(away.scans(engine.poses.copy(), engine.ticks), engine.scans())


def test_the_noise_differs_between_ticks_and_seeds(slim, robots, make_engine):
    waffle = robots["turtlebot3_waffle"]
    a = SwarmSensors(slim, [waffle] * 3, seed=1, control_period=0.1)
    b = SwarmSensors(slim, [waffle] * 3, seed=2, control_period=0.1)
    poses = np.array(POSES[:3], dtype=float)
    first, again, other = a.scans(poses, 0), a.scans(poses, 2), b.scans(poses, 0)
    finite = np.isfinite(first) & np.isfinite(again) & np.isfinite(other)
    assert finite.sum() > 100
    assert not np.array_equal(first[finite], again[finite])
    assert not np.array_equal(first[finite], other[finite])
    assert np.abs(first[finite] - again[finite]).max() < 0.2  # noise, not another world


def test_footprints_and_lidar_poses_follow_the_pose(slim, robots):
    waffle = robots["turtlebot3_waffle"]
    sensors = SwarmSensors(slim, [waffle], seed=0, control_period=0.1)
    pose = np.array([[3.0, 2.0, math.pi / 2]])
    feet = sensors.footprints(pose)[0]
    turned = np.column_stack((3.0 - waffle.footprint[:, 1], 2.0 + waffle.footprint[:, 0]))
    assert {tuple(p) for p in np.round(feet, 9)} == {tuple(p) for p in np.round(turned, 9)}
    mx, my, myaw = waffle.lidar.pose
    np.testing.assert_allclose(sensors.lidar_poses(pose)[0],
                               [3.0 - my, 2.0 + mx, math.pi / 2 + myaw], atol=1e-12)
    assert sensors.due_mask(0).tolist() == [True] and sensors.due_mask(1).tolist() == [False]


@pytest.mark.parametrize("mix", [False, True])
def test_a_late_renderer_skips_the_ticks_it_missed_and_renders_the_same(slim, robots, mix):
    waffle, burger = robots["turtlebot3_waffle"], robots["turtlebot3_burger"]
    models = [waffle, burger, waffle, burger] if mix else [waffle] * 4
    early = SwarmSensors(slim, models, seed=3, control_period=0.1)
    late = SwarmSensors(slim, models, seed=3, control_period=0.1)
    poses = np.array(POSES[:4], dtype=float)
    for ticks in range(1, 7):
        if early.due_mask(ticks).any():
            early.scans(poses, ticks)
        late.skip(ticks)  # nothing drawn where no lidar is due
    whole = early.scans(poses, 8)
    part = late.scans(poses, 8, [1, 2])
    _same(part, [whole[i] for i in (1, 2)] if mix else whole[[1, 2]])
