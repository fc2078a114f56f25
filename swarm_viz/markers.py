"""``/swarm/markers``: the fleet as one ``visualization_msgs/MarkerArray`` in ``map``.

RViz2 and Foxglove draw it without ``/tf``: every point is already in ``map`` (the odometry
frame coincides with it, docs/ARCHITECTURE.md).  One message holds, after a ``DELETEALL`` (so a
message is the whole picture and nothing stale stays):

========================  =====================  ======================================
namespace                 type                   what (id = robot or workstation index)
========================  =====================  ======================================
``footprint``             ``LINE_STRIP``         the robot's outline, coloured by state
``heading``               ``ARROW``              0.35 m along the robot's heading
``name``                  ``TEXT_VIEW_FACING``   its namespace, above it
``path``                  ``LINE_STRIP``         its global plan (only when it has one)
``workstation``           ``CUBE``               docking pose: green free, amber occupied,
                                                 red held
``workstation_name``      ``TEXT_VIEW_FACING``   the workstation's name
========================  =====================  ======================================
"""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point
from std_msgs.msg import ColorRGBA
from visualization_msgs.msg import Marker, MarkerArray

from swarm_common.geometry import transform_points
from swarm_common.nav_status import NavState
from swarm_viz.fleet_view import WS_FREE, WS_HELD, WS_OCCUPIED, FleetState, decimate

FRAME = "map"

STATE_RGB = {
    None: (0.6, 0.6, 0.6),
    NavState.IDLE: (0.6, 0.6, 0.6),
    NavState.PLANNING: (0.6, 0.6, 0.9),
    NavState.DRIVING: (0.16, 0.47, 0.95),
    NavState.HOLDING: (1.0, 0.55, 0.0),
    NavState.RECOVERING: (0.65, 0.3, 0.85),
    NavState.SUCCEEDED: (0.2, 0.75, 0.3),
    NavState.ABORTED: (0.9, 0.15, 0.15),
    NavState.CANCELED: (0.5, 0.5, 0.5),
}
"""Colour of a robot by its ``nav_status`` state (the page uses the same)."""
WS_RGB = {WS_FREE: (0.2, 0.75, 0.3), WS_OCCUPIED: (1.0, 0.75, 0.0), WS_HELD: (0.9, 0.15, 0.15)}


def _color(rgb, a: float = 1.0) -> ColorRGBA:
    return ColorRGBA(r=float(rgb[0]), g=float(rgb[1]), b=float(rgb[2]), a=a)


def _points(xy: np.ndarray, z: float = 0.0) -> list[Point]:
    return [Point(x=x, y=y, z=z) for x, y in xy.tolist()]


def _marker(ns: str, mid: int, kind: int, rgb, stamp) -> Marker:
    m = Marker()
    m.header.frame_id = FRAME
    m.header.stamp = stamp
    m.ns, m.id, m.type, m.action = ns, mid, kind, Marker.ADD
    m.pose.orientation.w = 1.0
    m.color = _color(rgb)
    return m


def fleet_markers(fleet: FleetState, footprint: np.ndarray, workstations, ws_states, stamp
                  ) -> MarkerArray:
    """The fleet's markers (see the module docstring).

    Args:
        fleet: the fleet's state (the caller holds its lock).
        footprint: (K, 2) robot outline in base_footprint [m]; or a sequence of every robot's
            own (a mixed fleet).
        workstations: :class:`swarm_scene.poi.Workstation` records.
        ws_states: their states (:func:`swarm_viz.fleet_view.workstation_states`).
        stamp: ``builtin_interfaces/Time`` of the markers.

    Returns:
        The message: a ``DELETEALL``, then the markers of every robot with a known pose and of
        every workstation.
    """
    out = MarkerArray()
    clear = Marker()
    clear.header.frame_id = FRAME
    clear.action = Marker.DELETEALL
    out.markers.append(clear)
    one = isinstance(footprint, np.ndarray) and footprint.ndim == 2
    rings = ([np.vstack((footprint, footprint[:1]))] * len(fleet.robots) if one else
             [np.vstack((np.asarray(f), np.asarray(f)[:1])) for f in footprint])
    for i, ns in enumerate(fleet.robots):
        pose = fleet.poses[i]
        if np.isnan(pose[0]):
            continue
        ring = rings[i]
        rgb = STATE_RGB.get(fleet.states[i], STATE_RGB[None])
        m = _marker("footprint", i, Marker.LINE_STRIP, rgb, stamp)
        m.scale.x = 0.03
        m.points = _points(transform_points(pose, ring), 0.02)
        out.markers.append(m)
        m = _marker("heading", i, Marker.ARROW, rgb, stamp)
        m.scale.x, m.scale.y, m.scale.z = 0.04, 0.08, 0.08
        tip = pose[:2] + 0.35 * np.array([np.cos(pose[2]), np.sin(pose[2])])
        m.points = _points(np.vstack((pose[:2], tip)), 0.05)
        out.markers.append(m)
        m = _marker("name", i, Marker.TEXT_VIEW_FACING, (1.0, 1.0, 1.0), stamp)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = float(pose[0]), float(
            pose[1]), 0.45
        m.scale.z = 0.22
        m.text = ns
        out.markers.append(m)
        path = fleet.paths[i]
        if path is not None and len(path) >= 2:
            m = _marker("path", i, Marker.LINE_STRIP, rgb, stamp)
            m.color.a = 0.6
            m.scale.x = 0.02
            m.points = _points(decimate(path), 0.01)
            out.markers.append(m)
    for k, (ws, state) in enumerate(zip(workstations, ws_states, strict=True)):
        m = _marker("workstation", k, Marker.CUBE, WS_RGB[state], stamp)
        m.pose.position.x, m.pose.position.y = float(ws.pose[0]), float(ws.pose[1])
        m.scale.x = m.scale.y = 0.4
        m.scale.z = 0.02
        m.color.a = 0.7
        out.markers.append(m)
        m = _marker("workstation_name", k, Marker.TEXT_VIEW_FACING, (1.0, 1.0, 1.0), stamp)
        m.pose.position.x, m.pose.position.y, m.pose.position.z = float(ws.pose[0]), float(
            ws.pose[1]), 0.35
        m.scale.z = 0.25
        m.text = ws.name
        out.markers.append(m)
    return out
