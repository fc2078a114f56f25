"""Collada meshes in worlds (issue 41): small .dae files written here load wherever STL and OBJ
do, with <unit>, node transforms and the SDF <scale> applied and <up_axis> ignored (as Gazebo
reads Collada), kept in their parts, so a ring of walls encloses its arena and a non-convex wall
does not fill it."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from swarm_scene.meshes import load_mesh
from swarm_scene.rasterize import rasterize_world
from swarm_scene.world import load_world, world_polygons

BOX_FACES = [(0, 2, 1), (0, 3, 2), (4, 5, 6), (4, 6, 7), (0, 1, 5), (0, 5, 4), (1, 2, 6),
             (1, 6, 5), (2, 3, 7), (2, 7, 6), (3, 0, 4), (3, 4, 7)]


def box(lo, hi) -> tuple[np.ndarray, list]:
    """(8, 3) corners of an axis-aligned box and its 12 triangles."""
    (x0, y0, z0), (x1, y1, z1) = lo, hi
    v = np.array([[x0, y0, z0], [x1, y0, z0], [x1, y1, z0], [x0, y1, z0],
                  [x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]], float)
    return v, BOX_FACES


def collada(pieces, unit: float | None = 1.0, up: str | None = "Z_UP", matrices=None) -> str:
    """A Collada document: one geometry and one node per (vertices, faces) piece."""
    asset = ""
    if unit is not None:
        asset += f'<unit name="u" meter="{unit}"/>'
    if up is not None:
        asset += f"<up_axis>{up}</up_axis>"
    geoms, nodes = [], []
    for k, (v, f) in enumerate(pieces):
        pos = " ".join(f"{x:.6f}" for x in np.asarray(v).ravel())
        idx = " ".join(str(i) for tri in f for i in tri)
        geoms.append(
            f'<geometry id="g{k}"><mesh><source id="g{k}-p"><float_array id="g{k}-a" '
            f'count="{len(v) * 3}">{pos}</float_array><technique_common><accessor '
            f'source="#g{k}-a" count="{len(v)}" stride="3"><param name="X" type="float"/>'
            '<param name="Y" type="float"/><param name="Z" type="float"/></accessor>'
            f'</technique_common></source><vertices id="g{k}-v"><input semantic="POSITION" '
            f'source="#g{k}-p"/></vertices><triangles count="{len(f)}"><input '
            f'semantic="VERTEX" source="#g{k}-v" offset="0"/><p>{idx}</p></triangles></mesh>'
            "</geometry>")
        m = "" if matrices is None else (
            "<matrix>" + " ".join(f"{x:g}" for x in np.asarray(matrices[k]).ravel())
            + "</matrix>")
        nodes.append(f'<node id="n{k}">{m}<instance_geometry url="#g{k}"/></node>')
    return ('<?xml version="1.0"?><COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema"'
            f' version="1.4.1"><asset>{asset}</asset><library_geometries>{"".join(geoms)}'
            '</library_geometries><library_visual_scenes><visual_scene id="s">'
            f'{"".join(nodes)}</visual_scene></library_visual_scenes><scene>'
            '<instance_visual_scene url="#s"/></scene></COLLADA>')


def world_with(tmp_path: Path, mesh_name: str, scale: str = "1 1 1",
               pose: str = "0 0 0 0 0 0") -> Path:
    path = tmp_path / "w.world"
    path.write_text(
        '<?xml version="1.0"?><sdf version="1.6"><world name="w"><model name="m">'
        f"<static>true</static><pose>{pose}</pose><link name='l'><collision name='c'>"
        f"<geometry><mesh><uri>{mesh_name}</uri><scale>{scale}</scale></mesh></geometry>"
        "</collision><visual name='v'><geometry><box><size>50 50 1</size></box></geometry>"
        "</visual></link></model></world></sdf>")
    return path


def ring_of_boxes(radius: float = 3.0, n: int = 6, thick: float = 0.2, height: float = 0.5):
    """n wall segments around the origin (a hexagon for 6), each an axis box turned by a node
    matrix: separate parts of one file."""
    side = 2 * radius * math.tan(math.pi / n) + thick
    pieces, mats = [], []
    for k in range(n):
        a = 2 * math.pi * k / n
        v, f = box((-thick / 2, -side / 2, 0.0), (thick / 2, side / 2, height))
        pieces.append((v, f))
        c, s = math.cos(a), math.sin(a)
        mats.append([[c, -s, 0, radius * c], [s, c, 0, radius * s], [0, 0, 1, 0], [0, 0, 0, 1]])
    return pieces, mats


def hexagon_band(radius: float = 3.0, thick: float = 0.2, height: float = 0.5):
    """One connected, non-convex hexagonal wall band (inner and outer hexagon, closed)."""
    ang = np.arange(6) * math.pi / 3
    outer = np.column_stack((radius * np.cos(ang), radius * np.sin(ang)))
    inner = outer * (radius - thick) / radius
    v = np.vstack([np.column_stack((outer, np.zeros(6))), np.column_stack((inner, np.zeros(6))),
                   np.column_stack((outer, np.full(6, height))),
                   np.column_stack((inner, np.full(6, height)))])
    f = []
    for i in range(6):
        j = (i + 1) % 6
        o0, o1, i0, i1 = i, j, 6 + i, 6 + j  # bottom
        O0, O1, I0, I1 = 12 + i, 12 + j, 18 + i, 18 + j  # top
        f += [(o0, i1, o1), (o0, i0, i1), (O0, O1, I1), (O0, I1, I0),  # bottom, top
              (o0, o1, O1), (o0, O1, O0), (i0, I1, i1), (i0, I0, I1)]  # outer, inner sides
    return v, f


def enclosed(occ, inside_xy, outside_xy) -> bool:
    """Whether no 4-connected free path leads from ``inside_xy`` to ``outside_xy``."""
    from scipy import ndimage

    free = occ.data == 0
    labels, _ = ndimage.label(free)
    a = occ.world_to_cell(np.array([inside_xy]))[0]
    b = occ.world_to_cell(np.array([outside_xy]))[0]
    return labels[a[0], a[1]] != labels[b[0], b[1]] and free[a[0], a[1]]


def test_a_collada_box_loads_with_its_unit_and_the_sdf_scale(tmp_path):
    # a 100 x 200 x 50 cm box in centimetres (unit 0.01), scaled 2 in x by the SDF
    v, f = box((0, 0, 0), (100, 200, 50))
    (tmp_path / "crate.dae").write_text(collada([(v, f)], unit=0.01))
    world = load_world(world_with(tmp_path, "crate.dae", scale="2 1 1"))
    assert world.skipped == ()
    (poly,) = world_polygons(world)
    np.testing.assert_allclose(poly.min(axis=0), [0.0, 0.0], atol=1e-6)
    np.testing.assert_allclose(poly.max(axis=0), [2.0, 2.0], atol=1e-6)
    mesh = load_mesh(tmp_path / "crate.dae")
    assert mesh.unit_m == 0.01 and len(mesh.parts) == 1 and mesh.parts[0].convex


def test_the_up_axis_is_ignored_as_gazebo_does_and_upper_case_dae_loads(tmp_path):
    # a box 2 m tall along z in a file that declares Y_UP (as SketchUp exports do): it stands
    # 2 m tall along z, its footprint 1 x 3 m, as in Gazebo and RViz2
    v, f = box((0, 0, 0), (1, 3, 2))
    (tmp_path / "TOWER.DAE").write_text(collada([(v, f)], up="Y_UP"))
    mesh = load_mesh(tmp_path / "TOWER.DAE")
    assert mesh.up_axis == "Y_UP"
    np.testing.assert_allclose(mesh.vertices.min(axis=0), [0, 0, 0], atol=1e-9)
    np.testing.assert_allclose(mesh.vertices.max(axis=0), [1, 3, 2], atol=1e-9)
    world = load_world(world_with(tmp_path, "TOWER.DAE"))
    assert world.skipped == ()
    (poly,) = world_polygons(world)
    np.testing.assert_allclose(poly.max(axis=0) - poly.min(axis=0), [1, 3], atol=1e-6)


def test_a_y_up_ring_of_z_up_wall_segments_maps_as_a_ring(tmp_path):
    """SketchUp's kind of file (ROBOTIS's wall.dae): Y_UP declared, z-up vertices, inches."""
    pieces, mats = ring_of_boxes()
    inch = 0.0254
    scaled = [(v / inch, f) for v, f in pieces]
    mats = [np.asarray(m, float) for m in mats]
    for m in mats:
        m[:3, 3] /= inch
    (tmp_path / "wall.dae").write_text(collada(scaled, unit=inch, up="Y_UP", matrices=mats))
    world = load_world(world_with(tmp_path, "wall.dae"))
    assert len(world_polygons(world)) == 6
    occ = rasterize_world(world, resolution=0.05, padding=1.0)
    assert enclosed(occ, (0.0, 0.0), (3.8, 0.0))
    assert occ.data[tuple(occ.world_to_cell(np.array([[0.0, 0.0]]))[0])] == 0  # centre free


def test_a_ring_of_wall_segments_keeps_its_parts_and_encloses_the_arena(tmp_path):
    pieces, mats = ring_of_boxes()
    (tmp_path / "wall.dae").write_text(collada(pieces, matrices=mats))
    mesh = load_mesh(tmp_path / "wall.dae")
    assert len(mesh.parts) == 6 and all(p.convex for p in mesh.parts)
    world = load_world(world_with(tmp_path, "wall.dae"))
    polys = world_polygons(world)
    assert len(polys) == 6
    occ = rasterize_world(world, resolution=0.05, padding=1.0)
    assert enclosed(occ, (0.0, 0.0), (3.8, 0.0))
    assert occ.data[tuple(occ.world_to_cell(np.array([[0.0, 0.0]]))[0])] == 0  # centre free


def test_one_non_convex_wall_band_is_its_triangles_not_its_hull(tmp_path):
    v, f = hexagon_band()
    (tmp_path / "hexagon.dae").write_text(collada([(v, f)]))
    (part,) = load_mesh(tmp_path / "hexagon.dae").parts
    assert not part.convex
    world = load_world(world_with(tmp_path, "hexagon.dae"))
    occ = rasterize_world(world, resolution=0.05, padding=1.0)
    free_share = float((occ.data == 0).mean())
    assert free_share > 0.5  # a hull would have filled the hexagon
    assert enclosed(occ, (0.0, 0.0), (3.6, 0.0))


def test_a_tall_non_convex_wall_is_drawn_from_its_vertical_faces(tmp_path):
    # 3 m tall: its top face is above the 2 m band, only the vertical faces reach into it
    v, f = hexagon_band(height=3.0)
    (tmp_path / "tall.dae").write_text(collada([(v, f)]))
    world = load_world(world_with(tmp_path, "tall.dae"))
    occ = rasterize_world(world, resolution=0.05, padding=1.0)
    assert enclosed(occ, (0.0, 0.0), (3.6, 0.0))


def test_collada_walls_stop_a_robot_and_its_lidar_sees_them(tmp_path):
    from swarm_scene.robot_model import load_robot
    from swarm_sim.engine import SimEngine

    v, f = hexagon_band(radius=2.0, thick=0.15)
    (tmp_path / "arena.dae").write_text(collada([(v, f)]))
    waffle = load_robot("turtlebot3_waffle")
    engine = SimEngine(load_world(world_with(tmp_path, "arena.dae")), waffle,
                       np.array([[0.0, 0.0, 0.0]]))
    try:
        scan = engine.scans()[0]
        hits = scan[np.isfinite(scan) & (scan < waffle.lidar.range_max)]
        assert len(hits) > 0.9 * len(scan) and hits.max() < 2.0  # the wall all round
        from tests.swarm_sim.test_engine import drive

        events = drive(engine, 0.26, 0.0, 200)  # 20 s at 0.26 m/s: 5 m, through the wall
        assert [e.kind for e in events] == ["robot_wall"]
        assert engine.poses[0, 0] < 2.0  # stopped at the wall, inside the arena
    finally:
        engine.close()


@pytest.mark.parametrize(("text", "reason"), [
    ('<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema"><asset><unit meter="-1"/>'
     "</asset><library_geometries/></COLLADA>", "<unit meter=-1.0> must be positive"),
    ("not xml at all", "not a Collada file"),
])
def test_a_broken_collada_file_is_named_with_why(tmp_path, text, reason):
    (tmp_path / "bad.dae").write_text(text)
    world = load_world(world_with(tmp_path, "bad.dae"))
    assert len(world.skipped) == 1 and reason in world.skipped[0]
    assert "replaced by the link's visual box 'v'" in world.skipped[0]


def test_a_warehouse_of_collada_shelves_shows_its_aisles(tmp_path):
    """Three rows of shelving, each row one .dae of five shelf units (separate parts), included
    three times as the AWS small warehouse does with its shelf models: the aisles between the
    rows stay free, the rows are occupied."""
    units = [box((k * 1.2, 0.0, 0.0), (k * 1.2 + 1.0, 0.8, 1.8)) for k in range(5)]
    (tmp_path / "shelves.DAE").write_text(collada(units))
    rows = "".join(
        f'<model name="row{i}"><static>true</static><pose>0 {i * 3.0} 0 0 0 0</pose>'
        "<link name='l'><collision name='c'><geometry><mesh><uri>shelves.DAE</uri></mesh>"
        "</geometry></collision></link></model>" for i in range(3))
    path = tmp_path / "warehouse.world"
    path.write_text(f'<?xml version="1.0"?><sdf version="1.6"><world name="w">{rows}'
                    "</world></sdf>")
    world = load_world(path)
    assert world.skipped == () and len(world_polygons(world)) == 15
    occ = rasterize_world(world, resolution=0.05)
    cell = lambda x, y: occ.data[tuple(occ.world_to_cell(np.array([[x, y]]))[0])]  # noqa: E731
    assert cell(0.5, 0.4) == 100 and cell(0.5, 3.4) == 100  # a shelf of rows 0 and 1
    assert cell(0.5, 1.9) == 0 and cell(3.0, 4.9) == 0  # the aisles between the rows
    assert cell(1.1, 0.4) == 0  # the gap between two shelf units of a row
