"""The simulator and the floor (issue 9, item 4): a robot drives on a floor slab, a loading
plate and a ground plane without a contact and without its lidar seeing them, and still bumps
into a 0.10 m pallet (swarm_scene.world.obstacle_shapes decides which is which)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from swarm_scene.robot_model import load_robot
from swarm_scene.world import load_world
from swarm_sim.engine import SimEngine

from .test_engine import drive

FLOOR = (
    # a slab the size of the floor, top 0.02 m above z = 0
    '<model name="slab"><static>true</static><pose>0 0 -0.03 0 0 0</pose><link name="l">'
    '<collision name="c"><geometry><box><size>12 12 0.1</size></box></geometry></collision>'
    '</link></model>'
    # a plate whose top is at the floor tolerance, 0.05 m
    '<model name="plate"><static>true</static><pose>2 0 0.035 0 0 0</pose><link name="l">'
    '<collision name="c"><geometry><box><size>1 3 0.03</size></box></geometry></collision>'
    '</link></model>'
    '<model name="ground"><static>true</static><link name="l"><collision name="c"><geometry>'
    '<plane><normal>0 0 1</normal><size>50 50</size></plane></geometry></collision></link>'
    '</model>'
)
PALLET = (
    # a pallet 0.10 m high on the slab (z 0.02 .. 0.12), its near side at x = 4.0
    '<model name="pallet"><static>true</static><pose>4.6 0 0.07 0 0 0</pose><link name="l">'
    '<collision name="c"><geometry><box><size>1.2 0.8 0.1</size></box></geometry>'
    '</collision></link></model>'
)


def _world(tmp_path: Path, body: str):
    path = tmp_path / "floor.world"
    path.write_text(f'<sdf version="1.7"><world name="w">{body}</world></sdf>')
    return load_world(path)


@pytest.fixture(scope="module")
def waffle():
    return load_robot("turtlebot3_waffle")


def test_driving_across_slab_and_plate_touches_nothing(tmp_path, waffle):
    engine = SimEngine(_world(tmp_path, FLOOR), waffle, np.array([[-4.0, 0.0, 0.0]]))
    try:
        events = drive(engine, 0.26, 0.0, 400)  # 40 s at 0.26 m/s: x -4 -> about +6
        assert events == []
        assert engine.collision_counts == {"robot_robot": 0, "robot_wall": 0}
        assert engine.poses[0, 0] > 5.0  # crossed the plate at x in [1.5, 2.5]
        scan = engine.scans()[0]
        # nothing within the lidar's range: the floor is not seen (no walls in this world)
        assert np.all(~np.isfinite(scan) | (scan >= waffle.lidar.range_max))
    finally:
        engine.close()


def test_a_low_pallet_on_the_slab_is_still_hit(tmp_path, waffle):
    engine = SimEngine(_world(tmp_path, FLOOR + PALLET), waffle, np.array([[0.0, 0.0, 0.0]]))
    try:
        events = drive(engine, 0.26, 0.0, 300)
        assert [(e.kind, e.other) for e in events] == [("robot_wall", "pallet::l::c")]
        # stopped with its front (0.069 m ahead of base_footprint) at the pallet's side, x = 4.0
        assert engine.poses[0, 0] + 0.069 == pytest.approx(4.0, abs=0.03)
    finally:
        engine.close()
