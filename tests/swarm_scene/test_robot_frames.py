"""A robot's description and joint frames (:mod:`swarm_scene.robot_frames`)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from swarm_common.errors import InputError
from swarm_scene.robot_frames import FOOTPRINT, frames_from_urdf, quaternion_from_rpy, robot_frames
from swarm_scene.robot_model import load_robot, resolve_robot


@pytest.mark.parametrize("rpy", [(0, 0, 0), (0.3, 0, 0), (0, -0.7, 0), (0, 0, 2.0),
                                 (0.1, 0.2, 0.3), (-1.2, 0.4, 3.0)])
def test_urdf_rpy_is_fixed_axis_roll_pitch_yaw(rpy):
    want = Rotation.from_euler("xyz", rpy).as_quat()  # lower case: extrinsic (fixed) axes
    got = np.array(quaternion_from_rpy(*rpy))
    assert np.allclose(got, want) or np.allclose(got, -want)


@pytest.mark.parametrize("robot", ["turtlebot3_waffle", "turtlebot3_burger", "linorobot2_2wd"])
def test_every_link_hangs_from_base_footprint_and_the_lidar_is_where_the_model_says(robot):
    frames = robot_frames(resolve_robot(robot))
    model = load_robot(robot)
    parent = {child: (p, pose) for p, child, pose in frames.joints}
    assert frames.root == FOOTPRINT
    assert f'<robot name="{robot}"' in frames.description
    # walk from the lidar's link up to base_footprint, composing the joints' poses
    link, xyz = model.lidar.frame, np.zeros(3)
    while link != FOOTPRINT:
        link, (x, y, z, qx, qy, qz, qw) = parent[link]
        xyz = Rotation.from_quat([qx, qy, qz, qw]).apply(xyz) + (x, y, z)
    assert tuple(xyz) == pytest.approx((*model.lidar.pose[:2], model.lidar.z), abs=1e-9)


def test_a_urdf_without_base_footprint_gets_one_at_its_root():
    urdf = """<robot name="r"><link name="base_link"/><link name="laser"/>
      <joint name="j" type="fixed"><parent link="base_link"/><child link="laser"/>
      <origin xyz="0.1 0 0.2" rpy="0 0 1.5707963267948966"/></joint></robot>"""
    frames = frames_from_urdf(urdf)
    assert frames.root == "base_link"
    assert frames.joints[0] == (FOOTPRINT, "base_link", (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0))
    parent, child, pose = frames.joints[1]
    assert (parent, child) == ("base_link", "laser")
    assert pose[:3] == (0.1, 0.0, 0.2)
    assert pose[5:] == pytest.approx((math.sin(math.pi / 4), math.cos(math.pi / 4)))


@pytest.mark.parametrize(("urdf", "words"), [
    ("<robot name='r'><link name='a'/>", "not XML"),
    ("<robot name='r'><link name='a'/><link name='b'/></robot>", "one tree, found 2 roots"),
    ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='fixed'>"
     "<child link='b'/></joint></robot>", "joint 'j' has no parent or child"),
    ("<robot name='r'><link name='a'/><link name='b'/><joint name='j' type='fixed'>"
     "<parent link='a'/><child link='b'/><origin xyz='1 x 2'/></joint></robot>",
     "not three numbers"),
])
def test_malformed_urdf_is_one_clear_error(urdf, words):
    with pytest.raises(InputError, match=words):
        frames_from_urdf(urdf, "bad.urdf")
