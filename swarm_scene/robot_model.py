"""Robot models from URDF/xacro: footprint, drive geometry, lidar and limits.

The contract: docs/reference/contract.md#s4, "Robots".

A robot is ``robots/<name>.urdf.xacro`` (or ``.urdf``), or a path to any ``.urdf``, ``.xacro`` or
``.urdf.xacro`` file.  xacro files are processed with the ``xacro`` package, the result is parsed
with ``yourdfpy`` (no meshes loaded: visual meshes are not needed headless) and reduced to what a
2D simulator and navigator need:

- the **footprint**, (K, 2) in ``base_footprint``, from the base link's collision geometry;
- the **wheel separation and radius** of the differential drive, from its two wheel joints;
- the **lidar**, from its Gazebo classic ``<gazebo reference=...><sensor type="ray">`` block
  (``yourdfpy`` ignores ``<gazebo>``; we read it with ``xml.etree``), or, when the URDF keeps the
  lidar's parameters elsewhere (as most published URDFs do), from the robot's params file or the
  documented LDS-01 defaults, with one warning;
- the **velocity and acceleration limits** from ``params/robots/<name>.yaml`` (nav2 names), and
  the radius a costmap inflates by (nav2's ``robot_radius``), from the same file when it has one.

Frames: every pose is in ``base_footprint`` (x forward, y left, z up, origin on the floor below
the drive axle centre, as REP 120 and nav2 define it).  A URDF without a ``base_footprint`` link
uses its root link's x, y and the lowest wheel contact point as the floor.

The numbers of the bundled robots come from ROBOTIS' ``turtlebot3_description`` URDFs and
``turtlebot3_navigation2`` params, and linorobot2's ``linorobot2_description`` and
``linorobot2_navigation`` configs; see the comments in ``robots/`` and ``params/robots/``.
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import logging
import math
import os
import pickle
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from swarm_common.errors import InputError, did_you_mean, unknown_name
from swarm_common.geometry import convex_hull_2d, pose_to_matrix
from swarm_common.paths import ROBOT_PARAMS_DIR, ROBOTS_DIR, ROOT, find_named

_log = logging.getLogger(__name__)

#: File name endings of a robot description, longest first.
ROBOT_SUFFIXES = (".urdf.xacro", ".urdf", ".xacro")

#: Link names a lidar usually has when its URDF carries no sensor block (REP 105 / TurtleBot3 /
#: linorobot2 / common vendor names), tried in this order; then ``*_laser``, ``*_lidar``.
LIDAR_LINK_NAMES = ("base_scan", "laser", "lidar", "laser_link", "lidar_link", "laser_frame")

#: ROBOTIS LDS-01 (HLS-LFCD-LDS) as simulated by turtlebot3_description's Gazebo sensor block and
#: specified in the TurtleBot3 e-Manual: 360 samples over 0..2pi, 0.12-3.5 m, 5 Hz, sigma 0.01 m.
LDS01_DEFAULTS: Mapping[str, float] = {
    "samples": 360,  # [-]
    "angle_min": 0.0,  # [rad]
    "angle_max": 2.0 * math.pi,  # [rad]
    "range_min": 0.12,  # [m]
    "range_max": 3.5,  # [m]
    "rate_hz": 5.0,  # [Hz]
    "noise_stddev": 0.01,  # [m]
}

_LIMIT_KEYS = ("max_vel_x", "min_vel_x", "max_vel_theta", "acc_lim_x", "acc_lim_theta")
_LIDAR_KEYS = tuple(LDS01_DEFAULTS)
_RAY_SENSOR_TYPES = ("ray", "gpu_ray", "lidar", "gpu_lidar")
_XACRO_NS = "http://ros.org/wiki/xacro"
_POLYGON_SIDES = 16  # cylinders and spheres become 16-gons in the footprint


@dataclass(frozen=True, eq=False)
class LidarSpec:
    """A planar lidar, as a ``sensor_msgs/LaserScan`` publisher needs it.

    The rays run from ``angle_min`` to ``angle_max`` inclusive, Gazebo's convention: the angle
    increment is ``(angle_max - angle_min) / (samples - 1)``.  Compared and hashed by identity
    (it holds an array).

    Attributes:
        frame: link name of the lidar, e.g. ``"base_scan"`` (with the xacro prefix, if any).
        samples: rays per scan [-].
        angle_min: angle of the first ray [rad], counter-clockwise from the lidar's +x.
        angle_max: angle of the last ray [rad].
        range_min: nearest valid return [m].
        range_max: farthest valid return [m].
        rate_hz: scans per second [Hz].
        noise_stddev: standard deviation of the Gaussian range noise [m].
        pose: (3,) x [m], y [m], yaw [rad] of the lidar in ``base_footprint``.
        z: height of the scan plane above the floor [m].
    """

    frame: str
    samples: int
    angle_min: float
    angle_max: float
    range_min: float
    range_max: float
    rate_hz: float
    noise_stddev: float
    pose: np.ndarray
    z: float


@dataclass(frozen=True)
class RobotLimits:
    """Velocity and acceleration limits of the base, with nav2's DWB parameter names.

    Attributes:
        max_vel_x: fastest forward speed [m/s].
        min_vel_x: fastest reverse speed [m/s] (negative when the base can back up).
        max_vel_theta: fastest turn rate, either direction [rad/s].
        acc_lim_x: linear acceleration limit [m/s^2].
        acc_lim_theta: angular acceleration limit [rad/s^2].
    """

    max_vel_x: float = 0.26  # [m/s]
    min_vel_x: float = -0.26  # [m/s]
    max_vel_theta: float = 1.82  # [rad/s]
    acc_lim_x: float = 2.5  # [m/s^2]
    acc_lim_theta: float = 3.2  # [rad/s^2]


#: Used for a robot without a limits file: TurtleBot3 waffle (e-Manual: 0.26 m/s, 1.82 rad/s;
#: turtlebot3_navigation2 waffle.yaml: 2.5 m/s^2, 3.2 rad/s^2).
DEFAULT_LIMITS = RobotLimits()


@dataclass(frozen=True, eq=False)
class RobotModel:
    """Everything the simulator and the navigator need to know about one robot model.

    Compared and hashed by identity (it holds arrays); :func:`load_robot` returns the same
    object for the same unchanged file, so it can key a cache.

    Attributes:
        name: the robot's name: its file name without ``.urdf``/``.xacro``/``.urdf.xacro``.
        source: the URDF or xacro file it was loaded from.
        footprint: (K, 2) convex polygon, x, y [m] in ``base_footprint``, counter-clockwise:
            the base link's collision geometry projected on the floor.
        radius: circumscribed radius of ``footprint`` about the ``base_footprint`` origin [m].
        height: top of the base collision geometry above the floor [m].
        wheel_separation: distance between the left and right wheel centres [m].
        wheel_radius: radius of the drive wheels [m].
        lidar: the lidar.
        limits: velocity and acceleration limits.
        costmap_radius: the radius a costmap inflates obstacles by for this robot [m] (nav2's
            ``robot_radius``): the limits file's ``robot_radius`` (the robot makers' nav2
            value), else :attr:`radius`.  The navigator's ``robot_radius`` (``swarm-up`` writes
            it per robot) comes from here.
    """

    name: str
    source: Path
    footprint: np.ndarray
    radius: float
    height: float
    wheel_separation: float
    wheel_radius: float
    lidar: LidarSpec
    limits: RobotLimits
    costmap_radius: float = math.nan  # [m]; _build always sets it


# --------------------------------------------------------------------------------------------
# Public API


def robot_names() -> list[str]:
    """Names of the robots under ``robots/`` (``<name>.urdf.xacro`` or ``<name>.urdf``), sorted."""
    if not ROBOTS_DIR.is_dir():
        return []
    names = {_stem(p) for p in ROBOTS_DIR.iterdir() if p.is_file() and _is_robot_file(p)}
    return sorted(names)


def resolve_robot(name_or_path: str | Path) -> Path:
    """Find a robot description file.

    Args:
        name_or_path: a name under ``robots/`` (``turtlebot3_waffle`` finds
            ``robots/turtlebot3_waffle.urdf.xacro``, else ``robots/turtlebot3_waffle.urdf``),
            or a path to a ``.urdf``, ``.xacro`` or ``.urdf.xacro`` file.

    Returns:
        The absolute path of the file.

    Raises:
        InputError: unknown name (the message lists the available robots, with a did-you-mean),
            missing file, or a file that is not ``.urdf``/``.xacro``.
    """
    text = str(name_or_path)
    if not (isinstance(name_or_path, Path) or "/" in text or Path(text).suffix):
        found = find_named(text, ROBOTS_DIR, (".urdf.xacro", ".urdf"))
        if found is not None:
            return found
        raise unknown_name(f"{_display(ROBOTS_DIR / (text + '.urdf.xacro'))}: ", "robot",
                           text, robot_names())
    path = Path(name_or_path).expanduser()
    if not _is_robot_file(path):
        raise InputError(f"{_display(path)}: not a robot description (expected .urdf, .xacro "
                         "or .urdf.xacro)")
    if not path.is_file():
        raise InputError(f"{_display(path)}: no such file")
    return path.resolve()


def load_robot(
    name_or_path: str | Path, *, xacro_args: Mapping[str, str] | None = None,
    need_meshes: bool = False,
) -> RobotModel:
    """Load a robot model from its URDF/xacro and its limits file.

    Loads are cached per file (and its modification time, and the limits file's), so loading
    the same robot for every robot of a swarm costs one parse; the returned arrays are
    read-only. Models are also cached on disk, keyed by their contents (``_load_cached``;
    ``SWARM_WB_CACHE_DIR=`` empty turns that off).

    Args:
        name_or_path: a name under ``robots/`` or a path to a ``.urdf``/``.xacro``/
            ``.urdf.xacro`` file (see :func:`resolve_robot`).
        xacro_args: ``xacro:arg`` values, e.g. ``{"prefix": "Srobot1/"}``; unset args take their
            defaults.
        need_meshes: whether the caller would draw the robot's meshes (a GUI). Mesh files that
            cannot be found (the bundled robots name ``package://turtlebot3_description``
            meshes, absent without that ROS package) are said once per file: as a warning when
            they are needed, else at debug level (the model itself never needs them).

    Returns:
        The robot model.  Limits come from ``params/robots/<name>.yaml``; for a robot given by
        path from ``<stem>.yaml`` beside the file, else ``params/robots/<stem>.yaml``, else
        :data:`DEFAULT_LIMITS` (TurtleBot3 waffle) with one warning.

    Raises:
        InputError: one line naming the file: unknown robot, missing file, xacro error, not XML,
            not a URDF, no base collision geometry, no pair of wheel joints, no lidar link,
            malformed sensor block, or a malformed limits file (unknown keys get a did-you-mean).
    """
    source = resolve_robot(name_or_path)
    limits_path = _limits_path(source, by_name=source.parent == ROBOTS_DIR.resolve())
    args = tuple(sorted((str(k), str(v)) for k, v in (xacro_args or {}).items()))
    model, missing = _load_cached(
        source, _mtime(source), args, limits_path, _mtime(limits_path) if limits_path else 0
    )
    if missing:
        _say_missing_meshes(source, missing, need_meshes)
    return model


def urdf_text(name_or_path: str | Path, xacro_args: Mapping[str, str] | None = None) -> str:
    """The URDF text of a robot (after xacro), as ``robot_state_publisher`` would be given it.

    Args:
        name_or_path: as :func:`load_robot`'s.
        xacro_args: as :func:`load_robot`'s.

    Raises:
        InputError: unknown robot, missing or unreadable file, xacro error.
    """
    return _process(resolve_robot(name_or_path), dict(xacro_args or {}))


def clear_robot_cache() -> None:
    """Forget the robots :func:`load_robot` has cached (e.g. after editing a file in a test)."""
    _load_cached.cache_clear()
    _meshes_said.clear()


def load_limits(path: str | Path) -> RobotLimits:
    """Load a limits file (``params/robots/<name>.yaml``).

    Args:
        path: the YAML file: ``max_vel_x`` [m/s], ``min_vel_x`` [m/s], ``max_vel_theta`` [rad/s],
            ``acc_lim_x`` [m/s^2], ``acc_lim_theta`` [rad/s^2], an optional ``robot_radius``
            [m] (nav2's costmap radius, :attr:`RobotModel.costmap_radius`) and an optional
            ``lidar:`` block.

    Returns:
        The limits.

    Raises:
        InputError: missing file, malformed YAML, a missing or unknown key, or a bad value.
    """
    return _read_params(Path(path))[0]


# --------------------------------------------------------------------------------------------
# Loading


@functools.lru_cache(maxsize=32)
def _load_cached(
    source: Path,
    _source_mtime: int,
    args: tuple[tuple[str, str], ...],
    limits_path: Path | None,
    _limits_mtime: int,
) -> tuple[RobotModel, tuple[str, ...]]:
    """The model of ``source`` and the mesh files it names that cannot be found.

    The model is also kept on disk (:func:`_disk_cache_dir`), keyed by everything it is made
    of: the URDF text after xacro, the source's path, the limits file's bytes, and the code
    and library versions that read them. A process that finds it there needs no ``yourdfpy``,
    whose import (trimesh, scipy.spatial) took 0.86 s of the 0.88 s a first load cost; every
    process of a run loads the robot (``swarm-up``, the simulator, each navigator process).
    A model whose making logged a warning is not kept, so the warning is logged every time.
    """
    text = _process(source, dict(args))
    key = _disk_key(source, text, limits_path)
    cached = _disk_get(key)
    if cached is not None:
        model, meshes = cached
    else:
        counter = _WarningCounter()
        _log.addHandler(counter)
        try:
            model, meshes = _build(source, text, limits_path)
        finally:
            _log.removeHandler(counter)
        if not counter.count:
            _disk_put(key, (model, meshes))
    missing = tuple(m for m in meshes if _resolve_mesh(m, source) is None)
    return model, missing


#: Bump when what a cached model holds changes meaning (the key also has this file's bytes).
_DISK_CACHE_VERSION = 2  # 2: RobotModel.costmap_radius


def _disk_cache_dir() -> Path | None:
    """``$SWARM_WB_CACHE_DIR/robots``, else ``$XDG_CACHE_HOME/swarm-workbench/robots`` (default
    ``~/.cache``); None when ``SWARM_WB_CACHE_DIR`` is set empty or no home directory is known
    (no disk cache)."""
    own = os.environ.get("SWARM_WB_CACHE_DIR")
    if own is not None:
        return Path(own) / "robots" if own else None
    base = os.environ.get("XDG_CACHE_HOME")
    if not base:
        home = os.path.expanduser("~")
        if home.startswith("~"):  # no home directory known: no disk cache
            return None
        base = os.path.join(home, ".cache")
    return Path(base) / "swarm-workbench" / "robots"


def _disk_key(source: Path, text: str, limits_path: Path | None) -> str | None:
    """A digest of what the model of ``source`` is made of; None when it cannot be read."""
    from importlib import metadata

    from swarm_common import geometry

    h = hashlib.blake2b(digest_size=20)
    try:
        for part in (str(_DISK_CACHE_VERSION), str(source), text,
                     np.__version__, metadata.version("yourdfpy")):
            h.update(part.encode("utf-8") + b"\0")
        for path in (Path(__file__), Path(geometry.__file__)):
            h.update(path.read_bytes())
        h.update(limits_path.read_bytes() if limits_path is not None else b"-")
    except (OSError, metadata.PackageNotFoundError):
        return None
    return h.hexdigest()


def _disk_get(key: str | None):
    """The cached ``(model, mesh names)`` of ``key``, or None (absent, unreadable, stale)."""
    folder = _disk_cache_dir()
    if key is None or folder is None:
        return None
    try:
        with open(folder / f"{key}.pickle", "rb") as f:
            model, meshes = pickle.load(f)
    except Exception:  # noqa: BLE001 - any unreadable entry is a miss; it is written again
        return None
    if not isinstance(model, RobotModel):
        return None
    _read_only(model)  # unpickled arrays are writeable again
    return model, tuple(meshes)


def _read_only(obj) -> None:
    """Make every array of a (nested) dataclass read-only, as a freshly made model's are."""
    for f in dataclasses.fields(obj):
        value = getattr(obj, f.name)
        if isinstance(value, np.ndarray):
            value.setflags(write=False)
        elif dataclasses.is_dataclass(value):
            _read_only(value)


def _disk_put(key: str | None, value) -> None:
    """Write an entry atomically (a temporary file renamed); a cache that cannot be written
    is no cache."""
    folder = _disk_cache_dir()
    if key is None or folder is None:
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
        with tempfile.NamedTemporaryFile(dir=folder, suffix=".tmp", delete=False) as f:
            pickle.dump(value, f, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(f.name, folder / f"{key}.pickle")
    except (OSError, pickle.PicklingError):
        try:
            os.unlink(f.name)
        except (OSError, NameError):
            pass


class _WarningCounter(logging.Handler):
    """Counts the warnings (and worse) logged while a model is made."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.count = 0

    def emit(self, record: logging.LogRecord) -> None:
        self.count += 1


def _build(source: Path, text: str, limits_path: Path | None
           ) -> tuple[RobotModel, tuple[str, ...]]:
    """The model of ``source`` from its URDF ``text``, and every mesh file name it has."""
    disp = _display(source)
    root = _parse_xml(text, disp)
    urdf = _parse_urdf(text, disp)
    meshes = _mesh_names(urdf)
    tree = _Tree(urdf, disp)

    wheels_y, wheel_radius, floor_z = _wheels(urdf, tree, disp)
    footprint, height = _base_outline(tree, floor_z, disp)

    costmap_radius = None
    if limits_path is not None:
        limits, lidar_params, costmap_radius = _read_params(limits_path)
    else:
        limits, lidar_params = DEFAULT_LIMITS, None
        _log.warning(
            "%s: no limits file (%s.yaml beside it or in %s); using the TurtleBot3 waffle "
            "defaults: max_vel_x %.2f m/s, max_vel_theta %.2f rad/s",
            disp, _stem(source), _display(ROBOT_PARAMS_DIR), limits.max_vel_x,
            limits.max_vel_theta,
        )
    lidar = _lidar(root, tree, floor_z, lidar_params, limits_path, disp)

    footprint.setflags(write=False)
    radius = float(np.max(np.hypot(footprint[:, 0], footprint[:, 1])))
    model = RobotModel(
        name=_stem(source),
        source=source,
        footprint=footprint,
        radius=radius,
        height=height,
        wheel_separation=wheels_y,
        wheel_radius=wheel_radius,
        lidar=lidar,
        limits=limits,
        costmap_radius=radius if costmap_radius is None else costmap_radius,
    )
    return model, meshes


def _process(source: Path, args: dict[str, str]) -> str:
    """The URDF text of ``source``, run through xacro when it needs it.

    ``.xacro`` files always are; so is a ``.urdf`` that declares the xacro namespace, as
    ROBOTIS' ``turtlebot3_*.urdf`` do (``xacro:arg namespace`` and ``${namespace}`` names).
    """
    disp = _display(source)
    try:
        raw = source.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{disp}: cannot read: {exc}") from None
    if source.name.endswith(".xacro") or _XACRO_NS in raw:
        import xacro  # imported lazily: it is only needed for xacro files

        from swarm_scene.resources import ament_index_with_ros_package_path

        try:
            with ament_index_with_ros_package_path():  # $(find pkg): ROS_PACKAGE_PATH too
                doc = xacro.process_file(str(source), mappings=dict(args))
        except Exception as exc:  # noqa: BLE001 - xacro raises many types; all are bad input
            detail = " ".join(str(exc).split()) or type(exc).__name__
            if type(exc).__name__ == "ExpatError":
                raise InputError(f"{disp}: not XML: {detail}") from None
            raise InputError(f"{disp}: xacro failed: {detail}") from None
        return doc.toxml()
    return raw


def _parse_xml(text: str, disp: str) -> ET.Element:
    try:
        root = ET.fromstring(text.encode("utf-8"))
    except ET.ParseError as exc:
        raise InputError(f"{disp}: not XML: {exc}") from None
    if root.tag != "robot":
        raise InputError(f"{disp}: not a URDF: root element is <{root.tag}>, expected <robot>")
    if not root.get("name"):
        raise InputError(f"{disp}: not a URDF: <robot> has no name attribute")
    return root


def _parse_urdf(text: str, disp: str):
    import yourdfpy  # imported lazily: trimesh and friends take a while to import

    try:
        urdf = yourdfpy.URDF.load(
            io.BytesIO(text.encode("utf-8")),
            build_scene_graph=False,
            build_collision_scene_graph=False,
            load_meshes=False,
            load_collision_meshes=False,
        )
        errors: list = []
        urdf.validate(validation_fn=lambda errs: errors.extend(errs) or not errs)
    except (AttributeError, KeyError, TypeError, ValueError, IndexError) as exc:
        raise InputError(f"{disp}: not a valid URDF: {type(exc).__name__}: {exc}") from None
    if errors:
        raise InputError(f"{disp}: not a valid URDF: {getattr(errors[0], 'msg', errors[0])}")
    if not urdf.robot.links:
        raise InputError(f"{disp}: not a valid URDF: no <link>")
    return urdf


def _mesh_names(urdf) -> tuple[str, ...]:
    """The mesh file names of the URDF's visuals and collisions, once each."""
    names: list[str] = []
    for link in urdf.robot.links:
        for element in (*link.visuals, *link.collisions):
            mesh = element.geometry.mesh if element.geometry is not None else None
            if mesh is not None and mesh.filename:
                names.append(mesh.filename)
    return tuple(dict.fromkeys(names))


_meshes_said: set[tuple[Path, bool]] = set()  # (source, as a warning) already logged


def _say_missing_meshes(source: Path, missing: tuple[str, ...], need_meshes: bool) -> None:
    """Log once per file that its meshes are missing: a warning if they would be drawn."""
    if (source, need_meshes) in _meshes_said:
        return
    _meshes_said.add((source, need_meshes))
    from swarm_scene.resources import describe, resolve

    first = describe(missing[0], resolve(missing[0], source.parent)[1])
    if need_meshes:
        _log.warning("%s: %d mesh file(s) not found (e.g. %s); the robot is drawn without them",
                     _display(source), len(missing), first)
    else:
        _log.debug("%s: %d mesh file(s) not found (e.g. %s); meshes are only drawn, not needed "
                   "headless: going on without them", _display(source), len(missing), first)


def _resolve_mesh(filename: str, source: Path) -> Path | None:
    """A mesh file of the URDF (:func:`swarm_scene.resources.resolve`: ``package://`` through
    the ament index and ``ROS_PACKAGE_PATH``), or None."""
    from swarm_scene.resources import resolve

    path = resolve(filename, source.parent)[0]
    return path if path is not None and path.is_file() else None


# --------------------------------------------------------------------------------------------
# Kinematic tree


class _Tree:
    """Link poses of a URDF in ``base_footprint`` (see the module docstring)."""

    def __init__(self, urdf, disp: str):
        self.disp = disp
        self.links = {link.name: link for link in urdf.robot.links}
        self.parent_joint = {}
        for joint in urdf.robot.joints:
            for end in (joint.parent, joint.child):
                if end not in self.links:
                    raise InputError(
                        f"{disp}: not a valid URDF: joint '{joint.name}' refers to an unknown "
                        f"link '{end}'"
                    )
            if joint.child in self.parent_joint:
                raise InputError(f"{disp}: not a valid URDF: link '{joint.child}' has two "
                                 "parent joints")
            self.parent_joint[joint.child] = joint
        roots = [name for name in self.links if name not in self.parent_joint]
        if len(roots) != 1:
            raise InputError(
                f"{disp}: not a valid URDF: the links must form one tree, found "
                f"{len(roots)} root links ({', '.join(roots[:4]) or 'a cycle'})"
            )
        self.root = roots[0]
        self._in_root: dict[str, np.ndarray] = {}
        footprint = _find_link(self.links, "base_footprint")
        self.frame = footprint if footprint is not None else self.root
        self._root_to_frame = np.linalg.inv(self.in_root(self.frame))

    def in_root(self, link: str) -> np.ndarray:
        """4x4 pose of ``link`` in the root link."""
        if link not in self._in_root:
            pose = np.eye(4)
            name, seen = link, set()
            while name in self.parent_joint:
                if name in seen:
                    raise InputError(f"{self.disp}: not a valid URDF: the joints form a cycle")
                seen.add(name)
                joint = self.parent_joint[name]
                origin = joint.origin if joint.origin is not None else np.eye(4)
                pose = origin @ pose
                name = joint.parent
            self._in_root[link] = pose
        return self._in_root[link]

    def pose(self, link: str) -> np.ndarray:
        """4x4 pose of ``link`` in ``base_footprint`` (the frame link)."""
        return self._root_to_frame @ self.in_root(link)

    def children(self, link: str) -> list[str]:
        return [j.child for j in self.parent_joint.values() if j.parent == link]


def _find_link(links: Mapping, name: str) -> str | None:
    """The link called ``name``, else the one link whose name ends with it (a xacro prefix)."""
    if name in links:
        return name
    hits = [n for n in links if n.endswith(name)]
    return hits[0] if len(hits) == 1 else None


def _origin(element) -> np.ndarray:
    return element.origin if getattr(element, "origin", None) is not None else np.eye(4)


# --------------------------------------------------------------------------------------------
# Geometry


def _shape_points(geometry) -> np.ndarray | None:
    """(N, 3) points whose hull is the shape (in the shape's frame), or None for a mesh."""
    angles = np.arange(_POLYGON_SIDES) * (2.0 * math.pi / _POLYGON_SIDES)
    if geometry.box is not None:
        sx, sy, sz = (float(v) / 2.0 for v in geometry.box.size)
        return np.array([[x, y, z] for x in (-sx, sx) for y in (-sy, sy) for z in (-sz, sz)])
    if geometry.cylinder is not None:
        r, half = float(geometry.cylinder.radius), float(geometry.cylinder.length) / 2.0
        ring = np.column_stack((r * np.cos(angles), r * np.sin(angles)))
        return np.vstack([np.column_stack((ring, np.full(len(ring), z))) for z in (-half, half)])
    if geometry.sphere is not None:
        r = float(geometry.sphere.radius)
        ring = np.column_stack((r * np.cos(angles), r * np.sin(angles), np.zeros(len(angles))))
        return np.vstack((ring, [[0.0, 0.0, -r], [0.0, 0.0, r]]))
    return None


def _shape_volume(geometry) -> float:
    if geometry is None:
        return 0.0
    if geometry.box is not None:
        return float(np.prod(geometry.box.size))
    if geometry.cylinder is not None:
        return math.pi * float(geometry.cylinder.radius) ** 2 * float(geometry.cylinder.length)
    if geometry.sphere is not None:
        return 4.0 / 3.0 * math.pi * float(geometry.sphere.radius) ** 3
    return 0.0


def _base_link(tree: _Tree) -> str:
    named = _find_link(tree.links, "base_link")
    if named is not None:
        return named
    candidates = [tree.root, *tree.children(tree.root)]

    def size(name: str) -> float:
        return max((_shape_volume(c.geometry) for c in tree.links[name].collisions), default=0.0)

    return max(candidates, key=size)


def _base_outline(tree: _Tree, floor_z: float, disp: str) -> tuple[np.ndarray, float]:
    """Footprint (K, 2) in base_footprint [m] and the base's top above the floor [m]."""
    base = _base_link(tree)
    link_pose = tree.pose(base)
    points = []
    for collision in tree.links[base].collisions:
        local = _shape_points(collision.geometry) if collision.geometry is not None else None
        if local is None:
            continue
        pose = link_pose @ _origin(collision)
        points.append(local @ pose[:3, :3].T + pose[:3, 3])
    if not points:
        raise InputError(
            f"{disp}: no base collision: link '{base}' has no <collision> with a box, cylinder "
            "or sphere (the footprint comes from the base collision geometry)"
        )
    allpts = np.vstack(points)
    footprint = convex_hull_2d(allpts[:, :2])
    if footprint is None:
        raise InputError(f"{disp}: no base collision: link '{base}' has a flat collision shape")
    return footprint, float(np.max(allpts[:, 2]) - floor_z)


def _wheels(urdf, tree: _Tree, disp: str) -> tuple[float, float, float]:
    """(wheel separation [m], wheel radius [m], floor z [m] in the frame link)."""
    left, right, radii, contacts = [], [], [], []
    for joint in urdf.robot.joints:
        if joint.type != "continuous":
            continue
        cylinders = [c for c in tree.links[joint.child].collisions
                     if c.geometry is not None and c.geometry.cylinder is not None]
        if not cylinders:
            continue
        child_pose = tree.pose(joint.child)
        axis = np.asarray(joint.axis if joint.axis is not None else (1.0, 0.0, 0.0), dtype=float)
        if not np.linalg.norm(axis) > 1e-9:
            continue
        axis_fp = child_pose[:3, :3] @ (axis / np.linalg.norm(axis))
        if abs(axis_fp[1]) < 0.9:  # a drive wheel turns about the lateral (y) axis
            continue
        centre = (child_pose @ _origin(cylinders[0]))[:3, 3]
        radius = float(cylinders[0].geometry.cylinder.radius)
        if centre[1] > 1e-6:
            left.append(centre[1])
        elif centre[1] < -1e-6:
            right.append(centre[1])
        else:
            continue
        radii.append(radius)
        contacts.append(centre[2] - radius)
    if not left or not right:
        raise InputError(
            f"{disp}: no wheel joints: need a left and a right continuous joint whose child link "
            "has a cylinder collision and turns about the lateral axis (a differential drive)"
        )
    # base_footprint lies on the floor by definition; without it, the wheels touch the floor
    floor_z = 0.0 if _find_link(tree.links, "base_footprint") is not None else min(contacts)
    separation = float(np.mean(left) - np.mean(right))
    return separation, float(np.mean(radii)), floor_z


# --------------------------------------------------------------------------------------------
# Lidar


def _lidar(root: ET.Element, tree: _Tree, floor_z: float, params: dict | None,
           params_path: Path | None, disp: str) -> LidarSpec:
    found = _ray_sensor(root, tree)
    if found is not None:
        link, sensor = found
        values, sensor_pose, missing = _read_sensor(sensor, link, disp)
        if missing:
            fallback, origin = _fallback_lidar(params, params_path)
            values.update({key: fallback[key] for key in missing})
            _log.warning(
                "%s: the sensor block of lidar '%s' has no %s; taking %s from %s",
                disp, link, "/".join(missing), ", ".join(f"{k}={fallback[k]:g}" for k in missing),
                origin,
            )
    else:
        link = _lidar_link(tree)
        if link is None:
            raise InputError(
                f"{disp}: no lidar: no <gazebo reference=...><sensor type=\"ray\"> block and no "
                f"link named {', '.join(LIDAR_LINK_NAMES)}, *_laser or *_lidar"
            )
        values, origin = _fallback_lidar(params, params_path)
        values = dict(values)
        sensor_pose = np.eye(4)
        _log.warning(
            "%s: no <gazebo><sensor type=\"ray\"> block for the lidar; using link '%s' with the "
            "%s: %d samples over [%.3f, %.3f] rad, %.2f-%.1f m, %.0f Hz, noise %.3f m",
            disp, link, origin, values["samples"], values["angle_min"], values["angle_max"],
            values["range_min"], values["range_max"], values["rate_hz"], values["noise_stddev"],
        )
    _check_lidar(values, disp, link)
    pose = tree.pose(link) @ sensor_pose
    xyyaw = np.array([pose[0, 3], pose[1, 3], math.atan2(pose[1, 0], pose[0, 0])])
    xyyaw.setflags(write=False)
    return LidarSpec(
        frame=link,
        samples=int(values["samples"]),
        angle_min=float(values["angle_min"]),
        angle_max=float(values["angle_max"]),
        range_min=float(values["range_min"]),
        range_max=float(values["range_max"]),
        rate_hz=float(values["rate_hz"]),
        noise_stddev=float(values["noise_stddev"]),
        pose=xyyaw,
        z=float(pose[2, 3] - floor_z),
    )


def _ray_sensor(root: ET.Element, tree: _Tree) -> tuple[str, ET.Element] | None:
    """The first ``<gazebo reference=LINK><sensor type="ray">`` whose LINK exists."""
    for gazebo in root.iter("gazebo"):
        link = gazebo.get("reference")
        if not link or link not in tree.links:
            continue
        for sensor in gazebo.findall("sensor"):
            if sensor.get("type") in _RAY_SENSOR_TYPES:
                return link, sensor
    return None


def _read_sensor(sensor: ET.Element, link: str, disp: str):
    """(values, 4x4 sensor pose in its link, names of values the block does not give)."""
    where = f"{disp}: sensor on link '{link}'"
    ray = sensor.find("ray")
    if ray is None:
        ray = sensor.find("lidar")  # Gazebo Sim (gz) spelling
    if ray is None:
        raise InputError(f"{where}: <sensor type=\"{sensor.get('type')}\"> has no <ray>")

    def number(path: str, element: ET.Element, required: bool = True) -> float | None:
        node = element.find(path)
        if node is None or node.text is None or not node.text.strip():
            if required:
                raise InputError(f"{where}: missing <{path}> in the sensor block")
            return None
        try:
            return float(node.text)
        except ValueError:
            raise InputError(f"{where}: <{path}> is not a number: {node.text.strip()!r}") from None

    values = {
        "samples": number("scan/horizontal/samples", ray),
        "angle_min": number("scan/horizontal/min_angle", ray),
        "angle_max": number("scan/horizontal/max_angle", ray),
        "range_min": number("range/min", ray),
        "range_max": number("range/max", ray),
    }
    if values["samples"] != int(values["samples"]):
        raise InputError(f"{where}: <samples> must be a whole number, got {values['samples']}")
    missing = []
    rate = number("update_rate", sensor, required=False)
    if rate is None or rate <= 0.0:
        missing.append("rate_hz")  # Gazebo's 0 = "every physics step": no rate to simulate
    else:
        values["rate_hz"] = rate
    noise = ray.find("noise")
    if noise is None:
        noise = sensor.find("noise")
    if noise is None or (noise.findtext("type") or "").strip() == "none":
        values["noise_stddev"] = 0.0  # Gazebo: no <noise>, no noise
    else:
        values["noise_stddev"] = number("stddev", noise, required=False) or 0.0
    pose = np.eye(4)
    pose_text = sensor.findtext("pose")
    if pose_text and pose_text.strip():
        try:
            x, y, z, roll, pitch, yaw = (float(v) for v in pose_text.split())
        except ValueError:
            raise InputError(f"{where}: <pose> must be 'x y z roll pitch yaw', got "
                             f"{pose_text.strip()!r}") from None
        pose = pose_to_matrix((x, y, z, roll, pitch, yaw))
    return values, pose, missing


def _lidar_link(tree: _Tree) -> str | None:
    """The lidar link by its usual names (see :data:`LIDAR_LINK_NAMES`), prefix allowed."""
    def base(name: str) -> str:
        return name.rsplit("/", 1)[-1]

    names = list(tree.links)
    for wanted in LIDAR_LINK_NAMES:
        for name in names:
            if base(name) == wanted:
                return name
    for suffix in ("_laser", "_lidar"):
        for name in names:
            if base(name).endswith(suffix):
                return name
    return None


def _fallback_lidar(params: dict | None, params_path: Path | None) -> tuple[dict, str]:
    """Lidar values from the params file's ``lidar:`` block over the LDS-01 defaults."""
    values = dict(LDS01_DEFAULTS)
    if params:
        values.update(params)
        return values, f"parameters of {_display(params_path)} (lidar:)"
    return values, "LDS-01 defaults"


def _check_lidar(values: Mapping[str, float], disp: str, link: str) -> None:
    where = f"{disp}: lidar '{link}'"
    for key, value in values.items():
        if not math.isfinite(float(value)):
            raise InputError(f"{where}: {key} must be finite, got {value}")
    if values["samples"] < 1:
        raise InputError(f"{where}: samples must be >= 1, got {values['samples']:g}")
    if values["angle_max"] <= values["angle_min"]:
        raise InputError(f"{where}: angle_max ({values['angle_max']:g} rad) must be greater "
                         f"than angle_min ({values['angle_min']:g} rad)")
    if not 0.0 <= values["range_min"] < values["range_max"]:
        raise InputError(f"{where}: need 0 <= range_min < range_max, got "
                         f"{values['range_min']:g}..{values['range_max']:g} m")
    if values["rate_hz"] <= 0.0:
        raise InputError(f"{where}: rate_hz must be > 0, got {values['rate_hz']:g}")
    if values["noise_stddev"] < 0.0:
        raise InputError(f"{where}: noise_stddev must be >= 0, got {values['noise_stddev']:g}")


# --------------------------------------------------------------------------------------------
# Limits file


def _limits_path(source: Path, by_name: bool) -> Path | None:
    stem = _stem(source)
    candidates = [ROBOT_PARAMS_DIR / f"{stem}.yaml"]
    if not by_name:
        candidates.insert(0, source.parent / f"{stem}.yaml")
    for candidate in candidates:
        if candidate.is_file():
            return candidate.resolve()
    return None


def _read_params(path: Path) -> tuple[RobotLimits, dict | None, float | None]:
    """(limits, the ``lidar:`` block as a dict or None, ``robot_radius`` [m] or None) of a
    limits file."""
    disp = _display(path)
    try:
        data = yaml.safe_load(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise InputError(f"{disp}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise InputError(f"{disp}: cannot read: {exc}") from None
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        where = f" (line {mark.line + 1})" if mark is not None else ""
        problem = getattr(exc, "problem", None) or "invalid YAML"
        raise InputError(f"{disp}: malformed YAML{where}: {problem}") from None
    if not isinstance(data, dict):
        raise InputError(f"{disp}: expected a mapping of limits ({', '.join(_LIMIT_KEYS)}), got "
                         f"{type(data).__name__}")
    allowed = (*_LIMIT_KEYS, "robot_radius", "lidar")
    for key in data:
        if key not in allowed:
            raise InputError(f"{disp}: unknown key '{key}'{did_you_mean(str(key), allowed)}; "
                             f"allowed: {', '.join(allowed)}")
    missing = [key for key in _LIMIT_KEYS if key not in data]
    if missing:
        raise InputError(f"{disp}: missing key(s) {', '.join(missing)}")
    values = {key: _number(data[key], f"{disp}: {key}") for key in _LIMIT_KEYS}
    for key in ("max_vel_x", "max_vel_theta", "acc_lim_x", "acc_lim_theta"):
        if values[key] <= 0.0:
            raise InputError(f"{disp}: {key} must be > 0, got {values[key]:g}")
    if values["min_vel_x"] > values["max_vel_x"]:
        raise InputError(f"{disp}: min_vel_x ({values['min_vel_x']:g} m/s) must not exceed "
                         f"max_vel_x ({values['max_vel_x']:g} m/s)")
    costmap_radius = None
    if data.get("robot_radius") is not None:
        costmap_radius = _number(data["robot_radius"], f"{disp}: robot_radius")
        if costmap_radius <= 0.0:
            raise InputError(f"{disp}: robot_radius must be > 0, got {costmap_radius:g}")
    lidar = None
    if data.get("lidar") is not None:
        block = data["lidar"]
        if not isinstance(block, dict):
            raise InputError(f"{disp}: lidar: expected a mapping of {', '.join(_LIDAR_KEYS)}")
        for key in block:
            if key not in _LIDAR_KEYS:
                raise InputError(f"{disp}: unknown key 'lidar.{key}'"
                                 f"{did_you_mean(str(key), _LIDAR_KEYS)}; allowed: "
                                 f"{', '.join(_LIDAR_KEYS)}")
        lidar = {key: _number(value, f"{disp}: lidar.{key}") for key, value in block.items()}
        if "samples" in lidar and lidar["samples"] != int(lidar["samples"]):
            raise InputError(f"{disp}: lidar.samples must be a whole number, got "
                             f"{lidar['samples']:g}")
        _check_lidar({**LDS01_DEFAULTS, **lidar}, disp, "lidar:")
    return RobotLimits(**values), lidar, costmap_radius


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"{where} must be a number, got {value!r}")
    if not math.isfinite(value):
        raise InputError(f"{where} must be finite, got {value!r}")
    return float(value)


# --------------------------------------------------------------------------------------------
# Names


def _is_robot_file(path: Path) -> bool:
    return path.name.endswith(ROBOT_SUFFIXES)


def _stem(path: Path) -> str:
    """File name without ``.urdf.xacro``/``.urdf``/``.xacro``."""
    for suffix in ROBOT_SUFFIXES:
        if path.name.endswith(suffix):
            return path.name[: -len(suffix)]
    return path.stem


def _mtime(path: Path) -> int:
    try:
        return path.stat().st_mtime_ns
    except OSError:
        return 0


def _display(path: Path | None) -> str:
    """``path`` relative to the repository root when inside it, else as given."""
    if path is None:
        return "?"
    try:
        return str(Path(path).resolve().relative_to(ROOT))
    except ValueError:
        return str(path)
