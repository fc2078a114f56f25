"""Gazebo worlds (SDF 1.6/1.7, later versions where they agree): the static collision geometry.

A world is read down to what a 2D swarm on one floor needs: every ``<collision>`` of every model,
as a box, cylinder, sphere or mesh with its full 6-DoF pose in the world frame (= ``map``).
Poses compose world ∘ model (∘ nested model ...) ∘ link ∘ collision, as SDF defines them: a
``<pose>`` is ``x y z roll pitch yaw`` (fixed axes, R = Rz(yaw) Ry(pitch) Rx(roll)) in its
parent's frame, or in the frame its ``relative_to`` attribute names (SDF 1.7 pose frame
semantics; SDF 1.6's ``frame`` attribute is read the same way; SDF 1.9's ``degrees`` and
``rotation_format`` are honoured).

A world saved by Gazebo applies its ``<state>`` on load: a model pose there overrides the
model's own ``<pose>``, here too.

Skipped silently: ``<include>`` of ``ground_plane`` and ``sun``, ``<light>``, visuals and world
settings (physics, scene, gui, plugins ...). An ``<include>`` of any other model is loaded when
its ``model://`` directory is found on the Gazebo model path (``GZ_SIM_RESOURCE_PATH``,
``IGN_GAZEBO_RESOURCE_PATH``, ``GAZEBO_MODEL_PATH``, ``SDF_PATH``, the world's own directory and
its ``models/``, ``~/.gazebo/models``). Everything else that cannot be represented (actors,
unresolvable includes, polyline/capsule/ellipsoid/... geometry, meshes that are not STL/OBJ or
cannot be found) is skipped and named once in :attr:`World.skipped`. Models that are not
``<static>`` are kept, at their initial pose: they are obstacles at the start.

The floor. Robots drive on the ground, so nothing they drive on is an obstacle: horizontal
``<plane>`` collisions and ``<heightmap>`` collisions are ground (named in :attr:`World.floor`,
the heightmap's relief is not modelled), and a solid shape is floor when its top is at or below
:data:`FLOOR_TOLERANCE` (a slab, platform or mat the size of the floor whose top is at z = 0 or a
few centimetres above). Everything that reaches into the robots' height band, above
``FLOOR_TOLERANCE`` and below :data:`BAND_TOP`, is an obstacle -- a 0.10 m pallet too. The rule
lives in :func:`obstacle_shapes`; the map (:func:`world_polygons`, ``swarm-map``), the spawn
check and the simulator's bodies all take their obstacles from it.

An unloadable mesh collision (``model://`` not found, or a ``.dae`` PyBullet cannot load) is
replaced when the file gives something in its place, in this order: the link's other collisions
(nothing added: they already stand for it), the primitive shapes (box, cylinder, sphere) of the
link's ``<visual>``s, or a loadable STL/OBJ visual mesh of the link. The skip report says which;
the same mesh file missing from many includes is one report (``... and 19 more``).

Sources: SDFormat specification (sdformat.org/spec, world/model/link/collision/geometry, and
"Pose frame semantics" for SDF 1.7), Gazebo classic's model path conventions.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from swarm_common.errors import InputError, did_you_mean, unknown_name
from swarm_common.geometry import (
    convex_hull_2d,
    matrix_to_pose,
    pose_to_matrix,
    quaternion_to_matrix,
    rpy_to_matrix,
)
from swarm_common.paths import WORLDS_DIR, find_named
from swarm_scene.meshes import MESH_SUFFIXES

WORLD_SUFFIXES = (".world", ".sdf")
# The robots' height band (ROS REP 103: z up, z = 0 the ground the robots stand on). A shape is
# an obstacle when it reaches above FLOOR_TOLERANCE and starts below BAND_TOP.
FLOOR_TOLERANCE = 0.05  # [m] a shape whose top is at or below this is floor (about a robot's
# step height: TurtleBot3's ground clearance is about 0.01 m, its wheels 0.066 m across)
BAND_TOP = 2.0  # [m] top of the band: above every robot body and lidar we simulate
POLYGON_SIDES = 32  # cylinders and spheres become circumscribed 32-gons in world_polygons

# World children that carry no geometry: ignored without a report.
_WORLD_SETTINGS = {
    "physics", "scene", "gui", "plugin", "gravity", "magnetic_field", "atmosphere", "wind",
    "spherical_coordinates", "state", "audio", "frame", "joint", "light", "model", "include",
    "actor", "population", "road",
}
_SILENT_INCLUDES = {"ground_plane", "groundplane", "sun"}
_MAX_INCLUDE_DEPTH = 16


@dataclass(frozen=True)
class CollisionShape:
    """One collision geometry of a world, posed in the world frame.

    Attributes:
        name: ``"<model>::<link>::<collision>"`` (nested models add ``::`` levels).
        kind: ``"box"``, ``"cylinder"``, ``"sphere"`` or ``"mesh"``.
        pose: (6,) read-only array: x, y, z [m] and roll, pitch, yaw [rad] of the shape's centre
            (the collision frame's origin) in the world frame (= ``map``); fixed-axis RPY.
        size: box ``(sx, sy, sz)`` [m]; cylinder ``(radius, length)`` [m], axis along its local
            z; sphere ``(radius,)`` [m]; mesh: the scale ``(sx, sy, sz)`` applied to its vertices.
        mesh_path: the resolved STL/OBJ file for a mesh, else ``None``.
    """

    name: str
    kind: str
    pose: np.ndarray
    size: tuple[float, ...]
    mesh_path: Path | None = None


@dataclass(frozen=True)
class World:
    """A loaded world.

    Attributes:
        name: the file's stem (``"slim_blockage"`` for ``worlds/slim_blockage.world``).
        source: the file it was read from, resolved.
        shapes: every supported collision shape, in document order, floor slabs included
            (:func:`obstacle_shapes` tells the obstacles from the floor).
        skipped: one entry per unsupported element (or per missing mesh file), each named
            once, e.g. ``"actor 'walker'"``; a replaced mesh says what stands for it.
        floor: the ground planes and heightmaps taken as the floor, by collision name.
    """

    name: str
    source: Path
    shapes: tuple[CollisionShape, ...]
    skipped: tuple[str, ...] = field(default_factory=tuple)
    floor: tuple[str, ...] = field(default_factory=tuple)


# --------------------------------------------------------------------------------------- resolve


def available_worlds() -> list[str]:
    """Names of the worlds bundled under ``worlds/`` (``.world`` and ``.sdf`` files), sorted."""
    if not WORLDS_DIR.is_dir():
        return []
    return sorted({p.stem for p in WORLDS_DIR.iterdir() if p.suffix in WORLD_SUFFIXES})


def resolve_world(name_or_path: str | Path) -> Path:
    """Find a world file: a name under ``worlds/`` or a path to a ``.world``/``.sdf`` file.

    Args:
        name_or_path: ``"slim_blockage"`` (looked up as ``worlds/slim_blockage.world``, then
            ``.sdf``), or a path. Anything with a directory part or a suffix is taken as a path.

    Returns:
        The resolved path of an existing file.

    Raises:
        InputError: the file does not exist, or the name is unknown (the message lists the
            available names with a did-you-mean).
    """
    text = str(name_or_path)
    path = Path(text).expanduser()
    if path.is_file():
        return path.resolve()
    is_path = isinstance(name_or_path, Path) or os.sep in text or path.suffix != ""
    if is_path:
        if path.is_dir():
            raise InputError(f"{text}: is a directory, not a .world/.sdf file")
        raise InputError(f"{text}: no such world file")
    found = find_named(text, WORLDS_DIR, WORLD_SUFFIXES)
    if found is not None:
        return found
    raise unknown_name("", "world", text, available_worlds(),
                       " (or give a path to a .world/.sdf file)")


# --------------------------------------------------------------------------------------- parsing


class _Loader:
    """One load: the file, the search path, the shapes found and the skip report."""

    def __init__(self, source: Path):
        self.source = source
        self.shapes: list[CollisionShape] = []
        self.skipped: list[str | _MeshSkip] = []
        self.floor: list[str] = []
        self.mesh_skips: dict[tuple[str, str], _MeshSkip] = {}

    # -- helpers ------------------------------------------------------------------------------

    def skip(self, what: str) -> None:
        if what not in self.skipped:
            self.skipped.append(what)

    def skip_mesh(self, where: str, uri: str, reason: str, stand_in: str) -> None:
        """Report an unloadable mesh once per (file, stand-in), counting its other uses."""
        key = (uri, reason + stand_in)
        entry = self.mesh_skips.get(key)
        if entry is None:
            entry = self.mesh_skips[key] = _MeshSkip(where, reason, stand_in)
            self.skipped.append(entry)
        else:
            entry.more += 1

    def skip_report(self) -> tuple[str, ...]:
        return tuple(str(s) for s in self.skipped)

    def fail(self, where: str, problem: str, source: Path | None = None) -> InputError:
        return InputError(f"{source or self.source}: {where}: {problem}")

    def floats(self, el: ET.Element, count: int, where: str, src: Path) -> list[float]:
        text = (el.text or "").strip()
        try:
            values = [float(v) for v in text.split()]
        except ValueError:
            values = []
        if len(values) != count or not all(math.isfinite(v) for v in values):
            raise self.fail(where, f"<{el.tag}> must be {count} numbers, got '{text}'", src)
        return values

    def scalar(self, parent: ET.Element, tag: str, where: str, src: Path,
               default: float | None = None) -> float:
        el = parent.find(tag)
        if el is None:
            if default is None:
                raise self.fail(where, f"missing <{tag}>", src)
            return default
        return self.floats(el, 1, where, src)[0]

    def pose(self, el: ET.Element | None, where: str, src: Path) -> np.ndarray:
        """(4, 4) transform of a ``<pose>`` element (identity if absent or empty)."""
        if el is None or not (el.text or "").strip():
            return np.eye(4)
        text = el.text.strip()
        fmt = el.get("rotation_format", "euler_rpy")
        count = 7 if fmt == "quat_xyzw" else 6
        values = self.floats(el, count, where, src)
        tf = np.eye(4)
        tf[:3, 3] = values[:3]
        if fmt == "quat_xyzw":
            tf[:3, :3] = quaternion_to_matrix(*values[3:])
        elif fmt == "euler_rpy":
            angles = values[3:]
            if el.get("degrees", "false").strip().lower() in ("true", "1"):
                angles = [math.radians(a) for a in angles]
            tf[:3, :3] = rpy_to_matrix(*angles)
        else:
            raise self.fail(where, f"<pose rotation_format='{fmt}'> is not euler_rpy or "
                            f"quat_xyzw (pose '{text}')", src)
        return tf

    @staticmethod
    def relative_to(el: ET.Element | None) -> str | None:
        if el is None:
            return None
        name = el.get("relative_to") or el.get("frame")
        return name.strip() if name and name.strip() else None

    # -- documents ----------------------------------------------------------------------------

    def parse_file(self, path: Path) -> ET.Element:
        try:
            text = path.read_bytes()
        except FileNotFoundError:
            raise InputError(f"{path}: no such file") from None
        except OSError as exc:
            raise InputError(f"{path}: cannot read: {exc.strerror or exc}") from None
        try:
            root = ET.fromstring(text)
        except ET.ParseError as exc:
            raise InputError(f"{path}: malformed XML: {exc}") from None
        return root

    def load(self) -> None:
        root = self.parse_file(self.source)
        base = self.source.parent
        if root.tag not in ("sdf", "world", "model"):
            raise InputError(f"{self.source}: not an SDF file (root element <{root.tag}>, "
                             "expected <sdf>)")
        worlds = [root] if root.tag == "world" else root.findall("world")
        if worlds:
            self.world(worlds[0], base)
            return
        models = [root] if root.tag == "model" else root.findall("model")
        if not models:
            raise InputError(f"{self.source}: no <world> or <model> element in <sdf>")
        for model in models:  # a model file loaded as a world of its own
            self.model(model, np.eye(4), "", base, self.source, depth=0)

    def world(self, world: ET.Element, base: Path) -> None:
        frames = _Frames(self, world, "world", base, self.source)
        # A world saved by Gazebo carries a <state> whose model poses (world frame) are applied
        # on load and override the models' own <pose>s (e.g. objects that settled).
        state = {}
        for state_el in world.findall("state"):
            for m in state_el.findall("model"):
                if m.get("name") and m.find("pose") is not None:
                    state[m.get("name")] = self.pose(m.find("pose"), f"state::{m.get('name')}",
                                                     self.source)
        for child in world:
            tag = child.tag
            if tag == "model":
                name = child.get("name", "model")
                pose = state[name] if name in state else frames.element_pose(child)
                self.model(child, pose, "", base, self.source, depth=0)
            elif tag == "include":
                self.include(child, frames, "", base, self.source, depth=0, state=state)
            elif tag in ("actor", "population", "road"):
                self.skip(f"{tag} '{child.get('name', '?')}'")
            elif tag not in _WORLD_SETTINGS:
                self.skip(f"<{tag}>")

    def model(self, model: ET.Element, world_T_model: np.ndarray, prefix: str, base: Path,
              src: Path, depth: int, name: str | None = None) -> None:
        name = name or model.get("name", "model")
        scoped = f"{prefix}{name}"
        frames = _Frames(self, model, "__model__", base, src, scope=scoped)
        for link in model.findall("link"):
            link_name = link.get("name", "link")
            world_T_link = world_T_model @ frames.element_pose(link)

            def world_T(el: ET.Element, where: str, link_tf=world_T_link) -> np.ndarray:
                pose_el = el.find("pose")
                rel = self.relative_to(pose_el)
                parent = link_tf if rel is None else world_T_model @ frames.pose_of(rel)
                return parent @ self.pose(pose_el, where, src)

            loaded, failed = 0, []
            for col in link.findall("collision"):
                where = f"{scoped}::{link_name}::{col.get('name', 'collision')}"
                outcome = self.collision(col, world_T(col, where), where, base, src)
                if outcome is True:
                    loaded += 1
                elif outcome:
                    failed.append((where, *outcome))
            if failed:
                stand_in = "the link's other collisions stand for it" if loaded else \
                    self.visual_stand_in(link, f"{scoped}::{link_name}", world_T, base, src)
                for where, uri, reason in failed:
                    self.skip_mesh(where, uri, reason, stand_in)
        for nested in model.findall("model"):
            self.model(nested, world_T_model @ frames.element_pose(nested), f"{scoped}::",
                       base, src, depth)
        for inc in model.findall("include"):
            self.include(inc, frames, f"{scoped}::", base, src, depth, world_T_model)

    def collision(self, col: ET.Element, world_T_col: np.ndarray, where: str, base: Path,
                  src: Path, mesh_report: bool = False) -> bool | tuple[str, str] | None:
        """Add the shape of a ``<collision>`` (or of a stand-in ``<visual>``).

        Returns:
            True when a shape was added; ``(uri, reason)`` for a mesh that cannot be loaded
            (the caller looks for a stand-in and reports it); None otherwise (floor, empty,
            or skipped and reported here).
        """
        geometry = col.find("geometry")
        shape = None if geometry is None else next(iter(geometry), None)
        if shape is None or shape.tag == "empty":
            return None
        kind = shape.tag
        pose = matrix_to_pose(world_T_col)
        pose.setflags(write=False)
        size: tuple[float, ...]
        mesh_path = None
        if kind == "box":
            size = tuple(self.floats(_required(shape, "size", self, where, src), 3, where, src))
        elif kind == "cylinder":
            size = (self.scalar(shape, "radius", where, src),
                    self.scalar(shape, "length", where, src))
        elif kind == "sphere":
            size = (self.scalar(shape, "radius", where, src),)
        elif kind == "plane":
            normal_el = shape.find("normal")
            normal = [0.0, 0.0, 1.0] if normal_el is None else self.floats(
                normal_el, 3, where, src)
            world_normal = world_T_col[:3, :3] @ np.asarray(normal, dtype=float)
            if abs(world_normal[2]) >= (1.0 - 1e-6) * np.linalg.norm(world_normal):
                self.floor.append(where)  # the ground: nothing a robot on it can hit
                return None
            self.skip(f"plane '{where}'")
            return None
        elif kind == "heightmap":
            self.floor.append(where)  # terrain used as the ground, taken as flat at z = 0
            return None
        elif kind == "mesh":
            mesh_path, uri, reason = self.mesh_file(shape, where, base, src)
            if mesh_path is None:
                if mesh_report:
                    return None
                return uri, reason
            scale_el = shape.find("scale")
            size = (1.0, 1.0, 1.0) if scale_el is None else tuple(
                self.floats(scale_el, 3, where, src))
        else:
            self.skip(f"{kind} '{where}'")
            return None
        degenerate = (0.0 in size) if kind == "mesh" else (min(size) <= 0.0)
        if degenerate:
            self.skip(f"{kind} '{where}' (size {' '.join(f'{s:g}' for s in size)})")
            return None
        self.shapes.append(CollisionShape(where, kind, pose, tuple(float(s) for s in size),
                                          mesh_path))
        return True

    def mesh_file(self, mesh: ET.Element, where: str, base: Path,
                  src: Path) -> tuple[Path | None, str, str]:
        """``(path, uri, "")`` of a loadable STL/OBJ mesh, else ``(None, uri, reason)``."""
        uri_el = mesh.find("uri")
        uri = (uri_el.text or "").strip() if uri_el is not None else ""
        if not uri:
            raise self.fail(where, "<mesh> without <uri>", src)
        from swarm_scene.resources import describe, resolve

        path, looked = resolve(uri, base)
        if path is None or not path.is_file():
            return None, uri, describe(uri, looked)
        if path.suffix.lower() not in MESH_SUFFIXES:
            return None, uri, f"{path.suffix or uri}: only STL, OBJ and Collada are loaded"
        try:
            _mesh_vertices(path)
        except ValueError as exc:
            return None, uri, f"{path.name}: {exc}"
        return path, uri, ""

    def visual_stand_in(self, link: ET.Element, scoped: str, world_T, base: Path,
                        src: Path) -> str:
        """Add the link's loadable visual geometry in place of its unloadable collision mesh.

        Primitive visuals (box, cylinder, sphere) first; else STL/OBJ visual meshes.

        Returns:
            What now stands for the mesh, for the report ("" when nothing does).
        """
        visuals = [v for v in link.findall("visual") if v.find("geometry") is not None]
        primitive = [v for v in visuals
                     if next(iter(v.find("geometry")), ET.Element("x")).tag in _PRIMITIVES]
        meshes = [v for v in visuals if v.find("geometry/mesh") is not None]
        for group in (primitive, meshes):
            added = []
            for vis in group:
                where = f"{scoped}::{vis.get('name', 'visual')}"
                kind = next(iter(vis.find("geometry"))).tag
                if self.collision(vis, world_T(vis, where), where, base, src,
                                  mesh_report=True) is True:
                    added.append(f"{kind} '{vis.get('name', 'visual')}'")
            if added:
                return f"replaced by the link's visual {', '.join(added)}"
        return ""

    def include(self, inc: ET.Element, frames: _Frames, prefix: str, base: Path, src: Path,
                depth: int, world_T_scope: np.ndarray | None = None,
                state: dict[str, np.ndarray] | None = None) -> None:
        uri_el = inc.find("uri")
        uri = (uri_el.text or "").strip() if uri_el is not None else ""
        if _include_base_name(uri) in _SILENT_INCLUDES:
            return
        label = f"include '{uri or inc.findtext('name', '?')}'"
        model_file = _find_model_file(uri, base) if uri else None
        if model_file is None or depth >= _MAX_INCLUDE_DEPTH:
            self.skip(label)
            return
        root = self.parse_file(model_file)
        model = root if root.tag == "model" else root.find("model")
        if model is None:
            self.skip(f"{label} (no <model> in {model_file.name})")
            return
        name = (inc.findtext("name") or "").strip() or model.get("name", "model")
        pose_el = inc.find("pose")
        if pose_el is None:
            pose_el = model.find("pose")
            local = self.pose(pose_el, f"{prefix}{name}", model_file)
            parent = np.eye(4)
        else:
            local = self.pose(pose_el, f"{prefix}{name}", src)
            rel = self.relative_to(pose_el)
            parent = np.eye(4) if rel is None else frames.pose_of(rel)
        scope_tf = np.eye(4) if world_T_scope is None else world_T_scope
        pose = scope_tf @ parent @ local
        if state and name in state:
            pose = state[name]
        self.model(model, pose, prefix, model_file.parent, model_file, depth + 1, name=name)


_PRIMITIVES = ("box", "cylinder", "sphere")


class _MeshSkip:
    """One report of an unloadable mesh: where it was first met and how many more uses."""

    def __init__(self, where: str, reason: str, stand_in: str):
        self.where, self.reason, self.stand_in, self.more = where, reason, stand_in, 0

    def __str__(self) -> str:
        more = f" and {self.more} more" if self.more else ""
        tail = f"; {self.stand_in}" if self.stand_in else ""
        return f"mesh '{self.where}'{more} ({self.reason}{tail})"


def _required(el: ET.Element, tag: str, loader: _Loader, where: str, src: Path) -> ET.Element:
    child = el.find(tag)
    if child is None:
        raise loader.fail(where, f"<{el.tag}> without <{tag}>", src)
    return child


class _Frames:
    """Poses of the named frames of one scope (a world or a model) in the scope's own frame.

    SDF 1.7 pose frame semantics: links, nested models and ``<frame>`` elements are posed in the
    scope frame unless ``relative_to`` names another frame of the same scope (``<frame>``
    defaults to its ``attached_to``); joints default to their child link.
    """

    def __init__(self, loader: _Loader, scope_el: ET.Element, root: str, base: Path, src: Path,
                 scope: str = "world"):
        self.loader, self.root, self.src, self.scope = loader, root, src, scope
        self.elements: dict[str, tuple[ET.Element, str]] = {}
        for child in scope_el:
            name = child.get("name")
            if not name:
                continue
            if child.tag in ("link", "model", "frame"):
                default = root
                if child.tag == "frame":
                    default = child.get("attached_to") or root
                self.elements.setdefault(name, (child, default))
            elif child.tag == "joint":
                self.elements.setdefault(name, (child, child.findtext("child", root).strip()))
        self.cache: dict[str, np.ndarray] = {root: np.eye(4)}
        if root == "world":
            self.cache["__model__"] = np.eye(4)

    def pose_of(self, name: str, chain: tuple[str, ...] = ()) -> np.ndarray:
        """(4, 4) pose of frame ``name`` in the scope frame; InputError on unknown names/cycles."""
        if name in self.cache:
            return self.cache[name]
        if name in chain:
            raise InputError(f"{self.src}: {self.scope}: pose frames form a cycle: "
                             f"{' -> '.join((*chain, name))}")
        if name not in self.elements:
            names = [self.root, *self.elements]
            raise InputError(f"{self.src}: {self.scope}: relative_to '{name}' names no frame"
                             f"{did_you_mean(name, names)}")
        el, default = self.elements[name]
        tf = self._compose(el, default, (*chain, name))
        self.cache[name] = tf
        return tf

    def element_pose(self, el: ET.Element) -> np.ndarray:
        """(4, 4) pose in the scope frame of a link, nested model or frame element of the scope."""
        default = self.root
        if el.tag == "frame":
            default = el.get("attached_to") or self.root
        return self._compose(el, default, (el.get("name", el.tag),))

    def _compose(self, el: ET.Element, default: str, chain: tuple[str, ...]) -> np.ndarray:
        pose_el = el.find("pose")
        rel = _Loader.relative_to(pose_el) or default
        local = self.loader.pose(pose_el, f"{self.scope}::{chain[-1]}", self.src)
        return self.pose_of(rel, chain) @ local


def _include_base_name(uri: str) -> str:
    """``"model://sun"`` → ``"sun"``; Fuel's ``.../models/Ground Plane/2`` → ``"ground_plane"``."""
    parts = [p for p in uri.replace("\\", "/").split("/") if p and not p.isdigit()]
    last = parts[-1] if parts else ""
    return last.strip().lower().replace(" ", "_")


def _resolve_uri(uri: str, base: Path) -> Path | None:
    """A file or directory for a URI (:func:`swarm_scene.resources.resolve`), or None."""
    from swarm_scene.resources import resolve

    return resolve(uri, base)[0]


def _find_model_file(uri: str, base: Path) -> Path | None:
    """The SDF file of an included model directory (via its model.config), or None."""
    target = _resolve_uri(uri, base)
    if target is None or not target.exists():
        return None
    if target.is_file():
        return target
    config = target / "model.config"
    if config.is_file():
        try:
            root = ET.parse(config).getroot()
        except ET.ParseError:
            root = None
        if root is not None:
            candidates = sorted(
                root.findall("sdf"),
                key=lambda e: tuple(int(p) for p in e.get("version", "0").split(".")
                                    if p.isdigit()),
            )
            for el in reversed(candidates):
                path = target / (el.text or "").strip()
                if path.is_file():
                    return path
    for fname in ("model.sdf", "model-1_7.sdf", "model-1_6.sdf"):
        if (target / fname).is_file():
            return target / fname
    return None


def _mesh_vertices(path: Path) -> np.ndarray:
    """(V, 3) vertices [m], z up, of a mesh file (:func:`swarm_scene.meshes.load_mesh`);
    ValueError if unreadable."""
    from swarm_scene.meshes import load_mesh

    return load_mesh(path).vertices


def load_world(name_or_path: str | Path) -> World:
    """Load a Gazebo world (or a model SDF) into its collision shapes.

    Args:
        name_or_path: a world name under ``worlds/`` or a path (see :func:`resolve_world`).

    Returns:
        The :class:`World`; its ``skipped`` names each unsupported element once.

    Raises:
        InputError: unknown name, missing file, malformed XML, a malformed number or pose, or a
            ``relative_to`` that names no frame (message: the file, then the problem).
    """
    source = resolve_world(name_or_path)
    loader = _Loader(source)
    loader.load()
    return World(name=source.stem, source=source, shapes=tuple(loader.shapes),
                 skipped=loader.skip_report(), floor=tuple(loader.floor))


# ----------------------------------------------------------------------------------- outlines


def describe_skipped(world: World) -> str | None:
    """The world's skip report as one warning line, as ``swarm-map`` and ``swarm-sim`` print it.

    Returns:
        e.g. ``"a.world: skipped unsupported elements: actor 'walker', road 'lane'"``; None
        when nothing was skipped.
    """
    if not world.skipped:
        return None
    return f"{world.source.name}: skipped unsupported elements: {', '.join(world.skipped)}"


def _shape_points(shape: CollisionShape) -> np.ndarray:
    """(P, 3) points in the world frame whose convex hull bounds the shape (conservatively)."""
    tf = pose_to_matrix(shape.pose)
    if shape.kind == "box":
        h = np.asarray(shape.size) / 2.0
        local = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    elif shape.kind in ("cylinder", "sphere"):
        radius = shape.size[0] / math.cos(math.pi / POLYGON_SIDES)  # circumscribed polygon
        ang = 2.0 * math.pi * (np.arange(POLYGON_SIDES) + 0.5) / POLYGON_SIDES
        ring = np.column_stack((radius * np.cos(ang), radius * np.sin(ang)))
        if shape.kind == "cylinder":
            half = shape.size[1] / 2.0
            local = np.vstack((np.column_stack((ring, np.full(len(ring), -half))),
                               np.column_stack((ring, np.full(len(ring), half)))))
        else:  # a sphere projects to the same circle whatever its orientation
            centre = tf[:3, 3]
            pts = np.column_stack((ring + centre[:2], np.full(len(ring), centre[2])))
            r = shape.size[0]
            return np.vstack((pts, [[*centre[:2], centre[2] - r], [*centre[:2], centre[2] + r]]))
    elif shape.kind == "mesh":
        local = _mesh_vertices(shape.mesh_path) * np.asarray(shape.size)
    else:
        raise ValueError(f"unknown shape kind {shape.kind!r}")
    return local @ tf[:3, :3].T + tf[:3, 3]


def shape_z_extent(shape: CollisionShape) -> tuple[float, float]:
    """Lowest and highest z [m] in ``map`` of a shape (exact for boxes, cylinders, spheres)."""
    if shape.kind in ("cylinder", "sphere"):
        return _round_extent_z(shape)
    pts = _shape_points(shape)
    return float(pts[:, 2].min()), float(pts[:, 2].max())


def obstacle_shapes(world: World, z_min: float = FLOOR_TOLERANCE,
                    z_max: float = BAND_TOP) -> list[CollisionShape]:
    """The shapes a robot can hit: those that reach into the height band ``(z_min, z_max)``.

    The one place that tells obstacles from the floor (module docstring, "The floor"): with the
    defaults, a slab or platform whose top is at or below :data:`FLOOR_TOLERANCE` (0.05 m) is
    floor the robots drive on, a 0.10 m pallet is an obstacle, and a beam that starts at or
    above :data:`BAND_TOP` (2.0 m) is over every robot's head.

    Args:
        world: the loaded world.
        z_min: bottom of the band [m]; a shape must reach strictly above it (1 nm tolerance).
        z_max: top of the band [m]; a shape must start strictly below it.

    Returns:
        The shapes of ``world.shapes`` in the band, in their order.
    """
    kept = []
    for shape in world.shapes:
        lo, hi = shape_z_extent(shape)
        if hi <= z_min + 1e-9 or lo >= z_max - 1e-9:
            continue
        kept.append(shape)
    return kept


def floor_shapes(world: World, z_min: float = FLOOR_TOLERANCE) -> list[CollisionShape]:
    """The shapes taken as floor: their top is at or below ``z_min`` [m] (see
    :func:`obstacle_shapes`)."""
    return [s for s in world.shapes if shape_z_extent(s)[1] <= z_min + 1e-9]


def world_polygons(world: World, z_min: float = FLOOR_TOLERANCE,
                   z_max: float = BAND_TOP) -> list[np.ndarray]:
    """The 2D outlines of the obstacles: the shapes that reach into a height band.

    Args:
        world: the loaded world.
        z_min: bottom of the band [m] (a shape must reach strictly above it: with the default
            :data:`FLOOR_TOLERANCE`, a floor slab whose top is at most 0.05 m high is not an
            obstacle; see :func:`obstacle_shapes`).
        z_max: top of the band [m] (a shape must start strictly below it).

    Returns:
        One convex polygon per shape whose z-extent overlaps ``(z_min, z_max)``, in the order of
        ``world.shapes``: a (K, 2) array of x, y [m] in ``map``, counter-clockwise. Boxes are
        exact (the hull of the projected corners, any orientation); cylinders and spheres are
        circumscribed 32-gons (so they contain the true outline); a mesh gives one polygon per
        part (:func:`swarm_scene.meshes.part_polygons`: a convex part's hull, a non-convex
        part's triangles). Shapes with no area in plan view are left out.
    """
    polygons = []
    for shape in obstacle_shapes(world, z_min, z_max):
        if shape.kind == "mesh":
            from swarm_scene.meshes import load_mesh, part_polygons

            tf = pose_to_matrix(shape.pose)
            for part in load_mesh(shape.mesh_path).parts:
                polygons += part_polygons(part, tf, shape.size, z_min, z_max)
            continue
        hull = convex_hull_2d(_shape_points(shape)[:, :2])
        if hull is not None:
            polygons.append(hull)
    return polygons


def _round_extent_z(shape: CollisionShape) -> tuple[float, float]:
    """Exact z-extent [m] of a cylinder or sphere (the polygon points overshoot slightly)."""
    z = float(shape.pose[2])
    if shape.kind == "sphere":
        return z - shape.size[0], z + shape.size[0]
    axis_z = pose_to_matrix(shape.pose)[2, 2]  # z component of the cylinder axis
    r, half = shape.size[0], shape.size[1] / 2.0
    reach = half * abs(axis_z) + r * math.sqrt(max(0.0, 1.0 - axis_z * axis_z))
    return z - reach, z + reach
