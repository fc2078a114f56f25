"""A robot's URDF as ``robot_state_publisher`` serves it: its description and its joint frames.

What the simulator's ``/tf_static`` and ``robot_description`` (:mod:`swarm_sim.tf_publisher`)
are made of: the URDF text after xacro (the bundled robots without a prefix: their links are
``base_footprint``, ``base_link``, ``base_scan``...; a robot's namespace prefixes them on
``/tf``), and for every joint its parent, child and origin.  Movable joints (the wheels) are
given at their zero position, as ``robot_state_publisher`` gives them before a ``joint_states``
message: the wheels are drawn, not turned.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

from swarm_common.errors import InputError

FOOTPRINT = "base_footprint"
"""The frame ``odom`` moves (REP 120); every odometry message's child frame."""


@dataclass(frozen=True)
class RobotFrames:
    """A robot model's description and frames.

    Attributes:
        description: the URDF text (after xacro).
        joints: ``(parent, child, (x, y, z, qx, qy, qz, qw))`` of every joint: the child link's
            pose in its parent link [m, quaternion], movable joints at zero.
        root: the URDF's root link; when it is not ``base_footprint``, ``joints`` starts with
            an identity ``base_footprint`` -> root joint (the root's x, y and heading are the
            robot's; its height above the floor is not known here).
    """

    description: str
    joints: tuple[tuple[str, str, tuple[float, ...]], ...]
    root: str


def quaternion_from_rpy(roll: float, pitch: float, yaw: float) -> tuple[float, float, float,
                                                                       float]:
    """The quaternion (x, y, z, w) of URDF's ``rpy`` (fixed axes: roll about x, then pitch
    about y, then yaw about z; the URDF specification, ``<origin>``)."""
    cr, sr = math.cos(roll / 2.0), math.sin(roll / 2.0)
    cp, sp = math.cos(pitch / 2.0), math.sin(pitch / 2.0)
    cy, sy = math.cos(yaw / 2.0), math.sin(yaw / 2.0)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def _floats(text: str | None, where: str) -> tuple[float, float, float]:
    parts = (text or "0 0 0").split()
    try:
        values = tuple(float(v) for v in parts)
    except ValueError:
        raise InputError(f"{where}: not three numbers: '{text}'") from None
    if len(values) != 3:
        raise InputError(f"{where}: not three numbers: '{text}'")
    return values  # type: ignore[return-value]


def frames_from_urdf(text: str, disp: str = "URDF") -> RobotFrames:
    """The frames of URDF ``text``.

    Raises:
        InputError: not XML, a joint without parent or child, an origin that is not numbers.
    """
    try:
        root = ET.fromstring(text.encode("utf-8"))
    except ET.ParseError as exc:
        raise InputError(f"{disp}: not XML: {exc}") from None
    links = [link.get("name") for link in root.findall("link")]
    joints: list[tuple[str, str, tuple[float, ...]]] = []
    children = set()
    for joint in root.findall("joint"):
        parent, child = joint.find("parent"), joint.find("child")
        if parent is None or child is None:
            raise InputError(f"{disp}: joint '{joint.get('name')}' has no parent or child")
        origin = joint.find("origin")
        where = f"{disp}: joint '{joint.get('name')}' origin"
        xyz = _floats(origin.get("xyz") if origin is not None else None, where)
        rpy = _floats(origin.get("rpy") if origin is not None else None, where)
        joints.append((parent.get("link"), child.get("link"), (*xyz, *quaternion_from_rpy(*rpy))))
        children.add(child.get("link"))
    roots = [name for name in links if name not in children]
    if len(roots) != 1:
        raise InputError(f"{disp}: the links must form one tree, found {len(roots)} roots")
    if roots[0] != FOOTPRINT and FOOTPRINT not in links:
        joints.insert(0, (FOOTPRINT, roots[0], (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)))
    return RobotFrames(text, tuple(joints), roots[0])


def robot_frames(source: Path) -> RobotFrames:
    """The frames of the robot file ``source`` (its URDF after xacro, no arguments).

    Raises:
        InputError: as :func:`swarm_scene.robot_model.urdf_text` and :func:`frames_from_urdf`.
    """
    from swarm_scene.robot_model import urdf_text

    return frames_from_urdf(urdf_text(source), str(source))
