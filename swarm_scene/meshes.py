"""Collision meshes of worlds: STL, OBJ and Collada, in metres, z up, kept in their parts.

A mesh file becomes a :class:`Mesh`: its triangles in the file's model frame converted to metres
and to z up, cut into *parts* (the connected components of its triangles), each marked convex
or not. How a part becomes collision geometry (our design; Gazebo hands meshes to its physics
engine as triangle meshes, and so do we where a hull would be wrong):

- a **convex** part is its convex hull: in the map and the lidar the hull of its projected
  vertices, in the simulator one convex body; a box or a cylinder exported as a mesh stays
  exact;
- a **non-convex** part (a wall that bends, a shelf with its compartments, a ring of walls in
  one piece) is its triangles: in the map and the lidar each triangle that reaches into the
  obstacle band is drawn as its plan-view projection, a vertical face as a strip
  :data:`WALL_STRIP_M` wide along its foot; in the simulator the part is a static concave
  triangle mesh (PyBullet's ``GEOM_FORCE_CONCAVE_TRIMESH``, for bodies that never move). So a
  wall mesh of segments never fills the arena it encloses.

Collada (``.dae``, any case; read by trimesh through pycollada) as Gazebo reads it: every
``<node>``'s geometry with its node transforms; ``<asset><unit meter="...">`` scales to metres;
``<asset><up_axis>`` is read (:attr:`Mesh.up_axis`) but **not applied**: the vertices are taken
as z up. Gazebo-classic's ``common/ColladaLoader.cc`` reads only ``<unit meter>`` from
``<asset>``, gz-common's loader (Harmonic and later) does the same, and RViz2 tells its mesh
importer to ignore the up direction; SketchUp exports (ROBOTIS's ``turtlebot3_world`` among
them) declare ``Y_UP`` over z-up data and rely on that. STL and OBJ are in metres, z up, as
Gazebo reads them. The SDF's ``<scale>`` applies on top (:mod:`swarm_scene.world`).
"""

from __future__ import annotations

import functools
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from pathlib import Path

import numpy as np

MESH_SUFFIXES = (".stl", ".obj", ".dae")
"""Loaded mesh formats, compared case-insensitively (``.DAE`` is Collada too)."""
WALL_STRIP_M = 0.02
"""[m] width of the plan-view strip a vertical triangle of a non-convex part is drawn as."""
UP_AXES = ("X_UP", "Y_UP", "Z_UP")
"""Collada's ``<up_axis>`` values; read and reported, never applied (module doc)."""


@dataclass(frozen=True)
class MeshPart:
    """One connected piece of a mesh.

    Attributes:
        vertices: (V, 3) read-only [m] in the mesh's frame, z up.
        faces: (F, 3) read-only vertex indices of its triangles.
        convex: whether the part is its own convex hull (within 1 mm).
    """

    vertices: np.ndarray
    faces: np.ndarray
    convex: bool


@dataclass(frozen=True)
class Mesh:
    """A mesh file's collision geometry (module doc).

    Attributes:
        parts: its connected pieces.
        unit_m: the file's unit [m] (Collada ``<unit meter>``; 1 for STL/OBJ).
        up_axis: the up axis the file declares (``Z_UP`` for STL/OBJ); not applied, as in
            Gazebo (module doc).
    """

    parts: tuple[MeshPart, ...]
    unit_m: float = 1.0
    up_axis: str = "Z_UP"

    @property
    def vertices(self) -> np.ndarray:
        """(V, 3) every part's vertices [m], z up."""
        return np.vstack([p.vertices for p in self.parts])


def is_mesh_file(path: Path) -> bool:
    """Whether ``path`` has a loadable mesh suffix (any case)."""
    return path.suffix.lower() in MESH_SUFFIXES


def collada_asset(path: Path) -> tuple[float, str]:
    """``(unit [m], up axis)`` of a Collada file's ``<asset>`` (the spec's defaults: 1.0 and
    ``Y_UP``).

    Raises:
        ValueError: not XML, a bad unit, or no ``<library_geometries>``.
    """
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as exc:
        raise ValueError(f"not a Collada file: {exc}") from None
    unit, up = 1.0, "Y_UP"
    asset = next((el for el in root if el.tag.rsplit("}", 1)[-1] == "asset"), None)
    for el in asset if asset is not None else ():
        tag = el.tag.rsplit("}", 1)[-1]
        if tag == "unit" and el.get("meter"):
            try:
                unit = float(el.get("meter"))
            except ValueError:
                raise ValueError(f"<unit meter={el.get('meter')!r}> is not a number") from None
        elif tag == "up_axis" and (el.text or "").strip() in UP_AXES:
            up = (el.text or "").strip()
    if not unit > 0:
        raise ValueError(f"<unit meter={unit!r}> must be positive")
    if not any(el.tag.rsplit("}", 1)[-1] == "library_geometries" for el in root):
        raise ValueError("a Collada file without geometry")
    return unit, up


@functools.lru_cache(maxsize=64)
def _load_cached(path: str, mtime: float) -> Mesh:
    import trimesh

    p = Path(path)
    unit, up = collada_asset(p) if p.suffix.lower() == ".dae" else (1.0, "Z_UP")
    try:
        if p.suffix.lower() == ".dae":
            scene = trimesh.load(path, force="scene", process=False)
            pieces = [g for g in scene.dump() if len(getattr(g, "faces", ())) > 0]
        else:
            pieces = [trimesh.load(path, force="mesh", process=False)]
    except Exception as exc:  # noqa: BLE001 - trimesh and pycollada raise many kinds
        raise ValueError(f"cannot load mesh: {' '.join(str(exc).split())[:200]}") from None
    rot = np.eye(3) * unit  # <up_axis> is not applied (module doc)
    parts = []
    for piece in pieces:
        verts = np.asarray(getattr(piece, "vertices", np.zeros((0, 3))), dtype=float)
        faces = np.asarray(getattr(piece, "faces", np.zeros((0, 3))), dtype=np.int64)
        if verts.ndim != 2 or len(verts) < 3 or faces.ndim != 2 or not len(faces):
            continue
        whole = trimesh.Trimesh(verts @ rot.T, faces, process=True)
        for comp in whole.split(only_watertight=False):
            parts.append(_part(comp))
    if not parts:
        raise ValueError("mesh has no vertices")
    return Mesh(tuple(parts), unit, up)


def _part(mesh) -> MeshPart:
    verts = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    convex = _is_convex(mesh)
    verts.setflags(write=False)
    faces.setflags(write=False)
    return MeshPart(verts, faces, convex)


def _is_convex(mesh) -> bool:
    """Whether every vertex lies within 1 mm of its convex hull's surface and the hull's volume
    is the mesh's (an open or flat piece is convex when it is a face of its hull)."""
    try:
        hull = mesh.convex_hull
    except Exception:  # noqa: BLE001 - qhull fails on flat or degenerate pieces
        return True
    if mesh.is_watertight and hull.volume > 1e-12:
        return abs(mesh.volume - hull.volume) <= 1e-3 * hull.volume + 1e-9
    import trimesh

    # open pieces: convex when every face lies on the hull's surface
    centres = mesh.triangles_center
    d = np.abs(trimesh.proximity.signed_distance(hull, centres)) if len(centres) else [0.0]
    return bool(np.max(d) <= 1e-3)


def load_mesh(path: Path) -> Mesh:
    """A mesh file's collision geometry (cached per path and modification time).

    Raises:
        ValueError: unreadable, not a mesh, or without triangles.
    """
    return _load_cached(str(path), path.stat().st_mtime)


def part_polygons(part: MeshPart, tf: np.ndarray, scale, z_min: float, z_max: float
                  ) -> list[np.ndarray]:
    """The plan-view outline(s) of one part placed in the world (module doc).

    Args:
        part: the part.
        tf: (4, 4) the mesh's pose in ``map``.
        scale: (3,) the SDF ``<scale>``.
        z_min, z_max: [m] the obstacle band: only what reaches into it counts.

    Returns:
        Convex polygons (K, 2) [m], counter-clockwise: one hull for a convex part that reaches
        into the band, else one per triangle that does (empty if none).
    """
    from swarm_common.geometry import convex_hull_2d

    world = (part.vertices * np.asarray(scale, float)) @ tf[:3, :3].T + tf[:3, 3]
    if part.convex:
        lo, hi = world[:, 2].min(), world[:, 2].max()
        if hi <= z_min + 1e-9 or lo >= z_max - 1e-9:
            return []
        hull = convex_hull_2d(world[:, :2])
        return [] if hull is None else [hull]
    tri = world[part.faces]  # (F, 3, 3)
    zlo, zhi = tri[:, :, 2].min(axis=1), tri[:, :, 2].max(axis=1)
    tri = tri[(zhi > z_min + 1e-9) & (zlo < z_max - 1e-9)][:, :, :2]
    out = []
    for a, b, c in tri:
        area2 = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])
        if abs(area2) > 2e-6:  # 1 mm^2
            out.append(np.array([a, b, c]) if area2 > 0 else np.array([a, c, b]))
            continue
        pts = np.array([a, b, c])  # a vertical face: a strip along its foot
        d = pts[:, None, :] - pts[None, :, :]
        i, j = np.unravel_index(np.argmax((d ** 2).sum(-1)), (3, 3))
        p, q = pts[i], pts[j]
        seg = q - p
        length = float(np.hypot(*seg))
        if length < 1e-6:
            continue
        n = np.array([-seg[1], seg[0]]) / length * (WALL_STRIP_M / 2.0)
        out.append(np.array([p - n, q - n, q + n, p + n]))
    return out
