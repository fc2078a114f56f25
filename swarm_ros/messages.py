"""Conversions between the project's pure types and ROS messages that several nodes share."""

from __future__ import annotations

import array
import math

import numpy as np
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import KeyValue
from nav_msgs.msg import OccupancyGrid

from swarm_common.stamps import NS_PER_S


def time_msg(t_ns: int) -> Time:
    """``builtin_interfaces/Time`` of ``t_ns`` [ns] (>= 0)."""
    return Time(sec=t_ns // NS_PER_S, nanosec=t_ns % NS_PER_S)


def stamp_ns(stamp) -> int:
    """[ns] of a ``builtin_interfaces/Time``."""
    return int(stamp.sec) * NS_PER_S + int(stamp.nanosec)


def key_values(values: dict) -> list[KeyValue]:
    """``diagnostic_msgs/KeyValue`` pairs of a record's encoded fields (values as strings)."""
    return [KeyValue(key=str(k), value=str(v)) for k, v in values.items()]


def occupancy_grid_msg(occ, stamp: Time) -> OccupancyGrid:
    """A :class:`swarm_scene.occupancy.OccupancyMap` as ``nav_msgs/OccupancyGrid`` in ``map``
    (its origin's yaw as a rotation about z), stamped ``stamp``."""
    msg = OccupancyGrid()
    msg.header.frame_id = "map"
    msg.header.stamp = stamp
    msg.info.map_load_time = stamp
    msg.info.resolution = float(occ.resolution)
    msg.info.width = occ.width
    msg.info.height = occ.height
    msg.info.origin.position.x = float(occ.origin[0])
    msg.info.origin.position.y = float(occ.origin[1])
    msg.info.origin.orientation.z = math.sin(float(occ.origin[2]) / 2.0)
    msg.info.origin.orientation.w = math.cos(float(occ.origin[2]) / 2.0)
    msg.data = array.array("b", np.ascontiguousarray(occ.data, dtype=np.int8).tobytes())
    return msg
