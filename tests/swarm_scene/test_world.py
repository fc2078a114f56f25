"""swarm_scene.world: SDF loading, pose composition, skipping, outlines."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from swarm_common.errors import InputError
from swarm_common.geometry import pose_to_matrix
from swarm_scene.world import (
    BAND_TOP,
    FLOOR_TOLERANCE,
    World,
    describe_skipped,
    floor_shapes,
    load_world,
    obstacle_shapes,
    resolve_world,
    shape_z_extent,
    world_polygons,
)

DATA = Path(__file__).resolve().parents[1] / "data"

# shared/reference/seed_facts.md, "World slim_blockage": x range, y range [m].
SEED_WALLS = {
    "bottom": ((-8.475, 9.525), (-4.974, -4.824)),
    "top": ((-8.475, 9.525), (9.376, 9.526)),
    "left": ((-8.475, -8.325), (-4.974, 9.526)),
    "right": ((9.375, 9.525), (-4.974, 9.526)),
    "blockage_left": ((-5.262, -5.112), (-3.016, 7.484)),
    "blockage_right": ((-3.912, -3.762), (-3.016, 7.484)),
    "blockage_bottom": ((-5.262, -3.762), (-3.016, -2.866)),
    "blockage_top": ((-5.262, -3.762), (7.334, 7.484)),
    "pocket_vertical": ((3.909, 4.059), (-4.912, -1.412)),
    "pocket_horizontal": ((3.909, 9.409), (-1.562, -1.412)),
}


def _shape(world: World, name: str):
    matches = [s for s in world.shapes if s.name == name]
    assert len(matches) == 1, [s.name for s in world.shapes]
    return matches[0]


def _compose(*poses) -> np.ndarray:
    """Independent reference: compose (6,) poses with scipy (extrinsic xyz = SDF rpy)."""
    tf = np.eye(4)
    for p in poses:
        step = np.eye(4)
        step[:3, :3] = Rotation.from_euler("xyz", p[3:]).as_matrix()
        step[:3, 3] = p[:3]
        tf = tf @ step
    return tf


# ------------------------------------------------------------------------------ slim_blockage


@pytest.fixture(scope="module")
def slim() -> World:
    return load_world("slim_blockage")


def test_slim_blockage_has_exactly_the_ten_seed_walls(slim):
    assert slim.name == "slim_blockage"
    assert slim.skipped == ()
    assert sorted(s.name.split("::")[1] for s in slim.shapes) == sorted(SEED_WALLS)
    assert all(s.kind == "box" for s in slim.shapes)


@pytest.mark.parametrize("wall", sorted(SEED_WALLS))
def test_slim_blockage_wall_extent_matches_seed_table(slim, wall):
    (x0, x1), (y0, y1) = SEED_WALLS[wall]
    shape = _shape(slim, f"slim_blockage::{wall}::collision")
    poly = world_polygons(World("w", slim.source, (shape,)))[0]
    assert poly.min(axis=0) == pytest.approx([x0, y0], abs=1e-6)  # to the micrometre
    assert poly.max(axis=0) == pytest.approx([x1, y1], abs=1e-6)
    assert min(shape.size[:2]) == pytest.approx(0.15, abs=1e-9)  # 0.15 m thick
    assert shape.size[2] == pytest.approx(2.5)  # 2.5 m high, standing on the floor
    assert shape.pose[2] == pytest.approx(1.25)


# --------------------------------------------------------------------------- pose composition


@pytest.fixture(scope="module")
def composition() -> World:
    return load_world(DATA / "world_composition.sdf")


def test_rotated_model_offset_link_and_collision_compose(composition):
    # model (1, 2, 0) yaw pi/2; link (1, 0, 0.5); collision (0, 0.5, 0) yaw pi/4:
    # link at (1, 2) + Rz(pi/2)(1, 0) = (1, 3); collision at (1, 3) + Rz(pi/2)(0, 0.5) = (0.5, 3)
    shape = _shape(composition, "rotated::arm::block")
    assert shape.kind == "box"
    assert shape.size == (0.4, 0.2, 1.0)
    assert shape.pose == pytest.approx([0.5, 3.0, 0.5, 0.0, 0.0, 3 * math.pi / 4], abs=1e-12)
    # its outline: a 0.4 x 0.2 rectangle turned by 3pi/4 about (0.5, 3.0)
    poly = world_polygons(World("w", composition.source, (shape,)))[0]
    half_diag = (0.2 + 0.1) * math.sqrt(0.5)  # |0.2 cos 45| + |0.1 sin 45|
    assert poly.min(axis=0) == pytest.approx([0.5 - half_diag, 3.0 - half_diag], abs=1e-12)
    assert poly.max(axis=0) == pytest.approx([0.5 + half_diag, 3.0 + half_diag], abs=1e-12)


def test_full_6dof_composition_matches_independent_reference(composition):
    expected = _compose([-3, 0, 1, 0.3, -0.4, 0.5], [0.2, -0.1, 0.3, 0.1, 0.2, -0.3],
                        [0.5, 0.0, -0.2, -0.6, 0.25, 1.0])
    shape = _shape(composition, "tilted::l::c")
    got = pose_to_matrix(shape.pose)
    np.testing.assert_allclose(got, expected, atol=1e-12)
    assert shape.pose[:3] == pytest.approx(expected[:3, 3], abs=1e-12)


def test_relative_to_a_model_frame(composition):
    # frame 'mount' at (0, 2) yaw pi/2 in model 'framed' at (5, 0):
    # link 'base' = mount ∘ (1, 0, 0) → (5, 3); collision of 'other' = mount ∘ (0, 1, 0.5) → (4, 2)
    assert _shape(composition, "framed::base::c").pose == pytest.approx(
        [5.0, 3.0, 0.0, 0.0, 0.0, math.pi / 2], abs=1e-12)
    assert _shape(composition, "framed::other::c").pose == pytest.approx(
        [4.0, 2.0, 0.5, 0.0, 0.0, math.pi / 2], abs=1e-12)


def test_nested_model_composes_and_is_named_with_both_models(composition):
    # outer at (0, -5) yaw pi; inner at (2, 0) in outer → (-2, -5)
    shape = _shape(composition, "outer::inner::l::c")
    assert shape.pose[:3] == pytest.approx([-2.0, -5.0, 0.5], abs=1e-12)
    assert abs(shape.pose[5]) == pytest.approx(math.pi, abs=1e-12)


def test_stl_mesh_outline_is_the_projected_hull(composition):
    shape = _shape(composition, "crate::l::c")
    assert shape.kind == "mesh"
    assert shape.mesh_path == DATA / "world_cube.stl"
    assert shape.size == (2.0, 1.0, 1.0)
    poly = world_polygons(World("w", composition.source, (shape,)))[0]
    # a 2 x 1 rectangle turned by pi/4 about (10, 0): corners at (10, 0) + R (±1, ±0.5)
    corners = np.array([[c * 1.0, s * 0.5] for c in (-1, 1) for s in (-1, 1)])
    rot = np.array([[math.cos(math.pi / 4), -math.sin(math.pi / 4)],
                    [math.sin(math.pi / 4), math.cos(math.pi / 4)]])
    expected = corners @ rot.T + [10.0, 0.0]
    assert len(poly) == 4
    for corner in expected:
        assert np.min(np.linalg.norm(poly - corner, axis=1)) < 1e-9


def test_composition_fixture_skips_ground_plane_sun_light_silently(composition):
    assert composition.skipped == ()
    assert len(composition.shapes) == 6


# --------------------------------------------------------------------------- skipping


def test_unsupported_elements_reported_once_each_by_name(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # a relative mesh is also looked for here (resources.py)
    for var in ("GAZEBO_RESOURCE_PATH", "GZ_SIM_RESOURCE_PATH"):
        monkeypatch.delenv(var, raising=False)
    world = load_world(DATA / "world_unsupported.world")
    statue = (f"mesh 'statue::link::collision' (meshes/missing_statue.stl not found (looked in: "
              f"{DATA}, {tmp_path}))")
    assert world.skipped == (
        "include 'model://turtlebot3_world'",  # included twice, reported once
        "actor 'walker'",
        "road 'lane'",
        "polyline 'fence::link::collision'",
        "polyline 'fence::link::collision_2'",
        statue,
    )
    # ground_plane, sun, light, scene, gui and the horizontal floor plane: silent
    assert not any("ground" in s or "sun" in s or "bulb" in s or "floor" in s
                   for s in world.skipped)
    # the ground plane and the heightmap are the floor, named there and not as skipped
    assert world.floor == ("floor::link::collision", "terrain::link::collision")
    # what is supported still loads
    assert [s.name for s in world.shapes] == ["wall::link::collision"]
    assert world.shapes[0].pose[:3] == pytest.approx([0.0, 3.0, 1.0])
    # the one warning line swarm-map and swarm-sim print
    assert describe_skipped(world) == (
        "world_unsupported.world: skipped unsupported elements: "
        "include 'model://turtlebot3_world', actor 'walker', road 'lane', "
        "polyline 'fence::link::collision', polyline 'fence::link::collision_2', " + statue)


def test_a_world_that_loads_whole_has_no_skip_line(composition):
    assert describe_skipped(composition) is None


def _write_world(tmp_path: Path, body: str, name: str = "w.world") -> Path:
    path = tmp_path / name
    path.write_text(f'<?xml version="1.0"?>\n<sdf version="1.6"><world name="w">{body}'
                    "</world></sdf>\n")
    return path


def _collision_model(name: str, geometry: str, pose: str = "0 0 0 0 0 0") -> str:
    return (f'<model name="{name}"><static>true</static><pose>{pose}</pose><link name="l">'
            f'<collision name="c"><geometry>{geometry}</geometry></collision></link></model>')


def test_vertical_plane_reported_dae_mesh_reported(tmp_path):
    (tmp_path / "statue.dae").write_text("<COLLADA/>")
    path = _write_world(tmp_path, _collision_model("screen", "<plane><normal>1 0 0</normal>"
                                                   "</plane>")
                        + _collision_model("statue", "<mesh><uri>statue.dae</uri></mesh>"))
    world = load_world(path)
    assert world.skipped == ("plane 'screen::l::c'",
                             "mesh 'statue::l::c' (statue.dae: a Collada file without geometry)")
    assert world.shapes == ()


def test_obj_mesh_loads_and_an_unreadable_stl_is_reported(tmp_path):
    # an OBJ octagonal prism, radius 0.5 m, height 1 m, about its centre
    ang = np.arange(8) * math.pi / 4
    ring = [(0.5 * math.cos(a), 0.5 * math.sin(a)) for a in ang]
    verts = [f"v {x:.9f} {y:.9f} {z}" for z in (-0.5, 0.5) for x, y in ring]
    faces = [f"f {i + 1} {(i + 1) % 8 + 1} {(i + 1) % 8 + 9} {i + 9}" for i in range(8)]
    (tmp_path / "prism.obj").write_text("\n".join(verts + faces) + "\n")
    (tmp_path / "broken.stl").write_text("solid broken\nfacet garbage\n")
    path = _write_world(tmp_path, _collision_model(
        "prism", "<mesh><uri>prism.obj</uri></mesh>", "2 1 0.5 0 0 0")
        + _collision_model("junk", "<mesh><uri>broken.stl</uri></mesh>"))
    world = load_world(path)
    assert world.skipped == ("mesh 'junk::l::c' (broken.stl: mesh has no vertices)",)
    (poly,) = world_polygons(world)
    assert len(poly) == 8
    np.testing.assert_allclose(np.linalg.norm(poly - [2.0, 1.0], axis=1), 0.5, atol=1e-9)


def test_include_of_a_model_found_on_the_model_path(tmp_path, monkeypatch):
    model_dir = tmp_path / "models" / "shelf"
    (model_dir / "meshes").mkdir(parents=True)
    (model_dir / "meshes" / "cube.stl").write_text((DATA / "world_cube.stl").read_text())
    (model_dir / "model.config").write_text(
        '<?xml version="1.0"?><model><name>shelf</name><sdf version="1.6">model.sdf</sdf>'
        "</model>")
    (model_dir / "model.sdf").write_text(
        '<?xml version="1.0"?><sdf version="1.6"><model name="shelf"><static>true</static>'
        '<pose>100 100 0 0 0 0</pose><link name="l"><pose>1 0 0 0 0 0</pose>'
        '<collision name="c"><geometry><mesh><uri>model://shelf/meshes/cube.stl</uri>'
        "</mesh></geometry></collision></link></model></sdf>")
    monkeypatch.setenv("GAZEBO_MODEL_PATH", str(tmp_path / "models"))
    world_dir = tmp_path / "w"
    world_dir.mkdir()
    path = _write_world(world_dir, "<include><uri>model://shelf</uri><name>shelf_a</name>"
                        "<pose>2 3 0 0 0 1.5707963267948966</pose></include>")
    world = load_world(path)
    assert world.skipped == ()
    (shape,) = world.shapes
    assert shape.name == "shelf_a::l::c"
    assert shape.mesh_path == model_dir / "meshes" / "cube.stl"
    # the include's pose replaces the model's own: (2, 3) + Rz(pi/2)(1, 0) = (2, 4)
    assert shape.pose == pytest.approx([2.0, 4.0, 0.0, 0.0, 0.0, math.pi / 2], abs=1e-12)


def test_saved_world_state_overrides_model_pose_and_empty_frame_attribute(tmp_path):
    """Gazebo classic's 'Save world': <pose frame=''> everywhere and a <state> applied on load."""
    path = _write_world(tmp_path, (
        "<model name='cube'><pose frame=''>1.6 -0.3 1.2 0 -0 1.56</pose><link name='link'>"
        "<pose frame=''>0 0 0.025 0 -0 0</pose><collision name='collision'><geometry><box>"
        "<size>0.046 0.046 0.046</size></box></geometry></collision></link></model>"
        "<model name='table'><pose frame=''>3 0 0 0 -0 0</pose><link name='link'>"
        "<collision name='c'><geometry><box><size>1 1 1</size></box></geometry></collision>"
        "</link></model>"
        "<state world_name='default'><sim_time>3028 346000000</sim_time>"
        "<model name='cube'><pose frame=''>1.6 -0.3 1.012 0 -0 1.56</pose><scale>1 1 1</scale>"
        "<link name='link'><pose frame=''>1.6 -0.3 1.037 0 -0 1.56</pose></link></model>"
        "<light name='sun'><pose frame=''>0 0 10 0 -0 0</pose></light></state>"))
    world = load_world(path)
    assert world.skipped == ()
    cube = _shape(world, "cube::link::collision")
    assert cube.pose == pytest.approx([1.6, -0.3, 1.037, 0.0, 0.0, 1.56], abs=1e-12)
    assert _shape(world, "table::link::c").pose[:3] == pytest.approx([3.0, 0.0, 0.0])


# --------------------------------------------------------------------------- outlines


def test_cylinder_and_sphere_are_circumscribed_32_gons(composition):
    sphere = _shape(composition, "framed::base::c")
    poly = world_polygons(World("w", composition.source, (sphere,)))[0]
    assert len(poly) == 32
    # every vertex at r / cos(pi/32) from the centre, so every edge touches the circle
    dist = np.linalg.norm(poly - [5.0, 3.0], axis=1)
    np.testing.assert_allclose(dist, 0.3 / math.cos(math.pi / 32), atol=1e-12)
    mids = (poly + np.roll(poly, -1, axis=0)) / 2.0
    np.testing.assert_allclose(np.linalg.norm(mids - [5.0, 3.0], axis=1), 0.3, atol=1e-12)
    x, y = poly[:, 0], poly[:, 1]
    assert np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)) > 0  # counter-clockwise


@pytest.mark.parametrize(("z_min", "z_max", "kept"), [
    (0.0, 2.0, ["post", "beam"]),     # default band
    (0.0, 1.0, ["post"]),             # the beam (z 1.5..1.7) is above the band
    (1.8, 3.0, ["post"]),             # only the 2 m post reaches 1.8..3
    (2.5, 3.0, []),
])
def test_world_polygons_height_band(tmp_path, z_min, z_max, kept):
    path = _write_world(tmp_path, "".join([
        _collision_model("slab", "<box><size>10 10 0.1</size></box>", "0 0 -0.05 0 0 0"),
        _collision_model("post", "<cylinder><radius>0.1</radius><length>2</length></cylinder>",
                         "0 0 1 0 0 0"),
        _collision_model("beam", "<box><size>3 0.2 0.2</size></box>", "5 0 1.6 0 0 0"),
    ]))
    world = load_world(path)
    polys = world_polygons(world, z_min, z_max)
    centres = [tuple(np.round(p.mean(axis=0), 6)) for p in polys]
    expected = {"post": (0.0, 0.0), "beam": (5.0, 0.0)}
    assert centres == [expected[k] for k in kept]  # the floor slab (top at z = 0) never


# --------------------------------------------------------------------------- resolve / errors


def test_resolve_world_by_name_and_by_path():
    by_name = resolve_world("slim_blockage")
    assert by_name.name == "slim_blockage.world"
    assert resolve_world(str(by_name)) == by_name
    assert resolve_world(by_name) == by_name


def test_unknown_world_name_lists_available_with_did_you_mean():
    with pytest.raises(InputError) as err:
        resolve_world("slim_blokage")
    msg = str(err.value)
    assert msg.startswith("unknown world 'slim_blokage' (did you mean 'slim_blockage'?)")
    assert "available: " in msg and "empty" in msg and "factory_floor" in msg
    assert "\n" not in msg


@pytest.mark.parametrize(("content", "problem"), [
    (None, "no such world file"),
    ("<sdf><world name='w'><model name='m'></world></sdf>", "malformed XML"),
    ("", "malformed XML"),
    ("<robot name='r'/>", "not an SDF file"),
    ("<sdf version='1.6'></sdf>", "no <world> or <model>"),
    ("<sdf><world name='w'><model name='m'><pose>1 2 x 0 0 0</pose></model></world></sdf>",
     "<pose> must be 6 numbers, got '1 2 x 0 0 0'"),
    ("<sdf><world name='w'><model name='m'><link name='l'><collision name='c'><geometry>"
     "<box><size>1 1</size></box></geometry></collision></link></model></world></sdf>",
     "m::l::c: <size> must be 3 numbers"),
    ("<sdf><world name='w'><model name='m'><link name='l'><collision name='c'><geometry>"
     "<cylinder><radius>1</radius></cylinder></geometry></collision></link></model></world>"
     "</sdf>", "missing <length>"),
    ("<sdf><world name='w'><model name='m'><link name='l'><pose relative_to='mout'>0 0 0 0 0 "
     "0</pose></link><frame name='mount'/></model></world></sdf>",
     "relative_to 'mout' names no frame (did you mean 'mount'?)"),
])
def test_bad_world_files_raise_one_line_naming_the_file(tmp_path, content, problem):
    path = tmp_path / "bad.world"
    if content is not None:
        path.write_text(content)
    with pytest.raises(InputError) as err:
        load_world(path)
    msg = str(err.value)
    assert msg.startswith(str(path) if content is not None else str(path))
    assert problem in msg
    assert "\n" not in msg


def test_world_is_frozen(slim):
    with pytest.raises(AttributeError):
        slim.name = "other"
    with pytest.raises(ValueError):
        slim.shapes[0].pose[0] = 1.0


# --------------------------------------------------------------------------- the floor rule


def _box_model(name: str, size: str, pose: str) -> str:
    return _collision_model(name, f"<box><size>{size}</size></box>", pose)


@pytest.mark.parametrize(("label", "model", "obstacle"), [
    # a slab the size of the floor, top at z = 0
    ("slab_top_0", _box_model("s", "20 14 0.1", "0 0 -0.05 0 0 0"), False),
    # the same slab, top 0.02 m above z = 0 (robots drive on it)
    ("slab_top_2cm", _box_model("s", "20 14 0.1", "0 0 -0.03 0 0 0"), False),
    # a platform whose top is exactly at the tolerance, 0.05 m
    ("platform_top_5cm", _box_model("s", "4 4 0.05", "0 0 0.025 0 0 0"), False),
    # a real but low obstacle: a 0.10 m pallet stays an obstacle
    ("pallet_10cm", _box_model("s", "1.2 0.8 0.1", "0 0 0.05 0 0 0"), True),
    # a kerb 6 cm high: just above the tolerance
    ("kerb_6cm", _box_model("s", "3 0.2 0.06", "0 0 0.03 0 0 0"), True),
    # a pallet standing on a 0.02 m slab (0.02 .. 0.12 m)
    ("pallet_on_slab", _box_model("s", "1.2 0.8 0.1", "0 0 0.07 0 0 0"), True),
    # a beam that starts at 2.0 m: above every robot
    ("beam_at_2m", _box_model("s", "3 0.2 0.2", "0 0 2.1 0 0 0"), False),
    # a lying cylinder (a pipe) of radius 0.04 m on the floor: top at 0.08 m
    ("pipe_r4cm", _collision_model("s", "<cylinder><radius>0.04</radius><length>2</length>"
                                   "</cylinder>", "0 0 0.04 1.5707963 0 0"), True),
])
def test_floor_rule_tells_slabs_from_low_obstacles(tmp_path, label, model, obstacle):
    world = load_world(_write_world(tmp_path, model))
    assert len(world.shapes) == 1
    assert (len(obstacle_shapes(world)) == 1) is obstacle
    assert (len(world_polygons(world)) == 1) is obstacle
    # floor: what is not an obstacle, except what is over the robots' heads
    assert (len(floor_shapes(world)) == 1) is (not obstacle and label != "beam_at_2m")


def test_floor_rule_constants_and_defaults():
    assert FLOOR_TOLERANCE == 0.05 and BAND_TOP == 2.0
    import inspect

    for fn in (obstacle_shapes, world_polygons):
        params = inspect.signature(fn).parameters
        assert params["z_min"].default == FLOOR_TOLERANCE
        assert params["z_max"].default == BAND_TOP


def test_ground_plane_and_heightmap_are_floor_and_named(tmp_path):
    path = _write_world(tmp_path, "".join([
        _collision_model("ground", "<plane><normal>0 0 1</normal><size>50 50</size></plane>"),
        _collision_model("hills", "<heightmap><uri>file://terrain.png</uri><size>129 129 10"
                                  "</size><pos>0 0 0</pos></heightmap>"),
        _box_model("wall", "4 0.2 2", "0 3 1 0 0 0"),
    ]))
    world = load_world(path)
    assert world.floor == ("ground::l::c", "hills::l::c")
    assert world.skipped == ()
    assert [s.name for s in obstacle_shapes(world)] == ["wall::l::c"]


# --------------------------------------------------------------------------- mesh stand-ins


def _link_model(name: str, link_body: str, pose: str = "0 0 0 0 0 0") -> str:
    return (f'<model name="{name}"><static>true</static><pose>{pose}</pose>'
            f'<link name="l">{link_body}</link></model>')


@pytest.fixture
def no_model_path(monkeypatch):
    """No Gazebo model path variable set: the places looked in are the world's own."""
    from swarm_scene.resources import MODEL_PATH_VARS

    for var in MODEL_PATH_VARS:
        monkeypatch.delenv(var, raising=False)


def test_missing_mesh_with_a_sibling_box_collision_is_reported_once(tmp_path, no_model_path):
    body = ('<collision name="mesh"><geometry><mesh><uri>model://crate/meshes/crate.dae</uri>'
            '</mesh></geometry></collision>'
            '<collision name="box"><pose>0 0 0.5 0 0 0</pose><geometry><box><size>1 1 1</size>'
            '</box></geometry></collision>')
    world = load_world(_write_world(tmp_path, _link_model("crate", body, "3 0 0 0 0 0")))
    assert world.skipped == (
        f"mesh 'crate::l::mesh' (model://crate/meshes/crate.dae not found (looked in: {tmp_path}, "
        f"{tmp_path}/models, {Path.home()}/.gazebo/models); the link's other collisions stand "
        "for it)",)
    assert [s.name for s in world.shapes] == ["crate::l::box"]


def test_missing_collision_mesh_replaced_by_the_visual_box(tmp_path, no_model_path):
    body = ('<collision name="c"><geometry><mesh><uri>model://bench/meshes/bench.dae</uri>'
            '</mesh></geometry></collision>'
            '<visual name="v"><pose>0 0.5 0.4 0 0 0</pose><geometry><box><size>2 0.6 0.8'
            '</size></box></geometry></visual>')
    world = load_world(_write_world(tmp_path, _link_model("bench", body, "1 2 0 0 0 1.5707963")))
    assert world.skipped == (
        f"mesh 'bench::l::c' (model://bench/meshes/bench.dae not found (looked in: {tmp_path}, "
        f"{tmp_path}/models, {Path.home()}/.gazebo/models); replaced by the link's visual box "
        "'v')",)
    (shape,) = world.shapes
    assert shape.name == "bench::l::v" and shape.kind == "box"
    # model yaw 90 deg: the visual's (0, 0.5) offset goes to -x in the world
    np.testing.assert_allclose(shape.pose[:3], [0.5, 2.0, 0.4], atol=1e-7)
    (poly,) = world_polygons(world)
    np.testing.assert_allclose(poly.min(axis=0), [0.2, 1.0], atol=1e-7)
    np.testing.assert_allclose(poly.max(axis=0), [0.8, 3.0], atol=1e-7)


def test_dae_collision_replaced_by_an_stl_visual_mesh(tmp_path):
    import shutil

    shutil.copy(DATA / "world_cube.stl", tmp_path / "cube.stl")
    (tmp_path / "cube.dae").write_text("<COLLADA/>")
    body = ('<collision name="c"><geometry><mesh><uri>cube.dae</uri></mesh></geometry>'
            '</collision><visual name="v"><geometry><mesh><uri>cube.stl</uri></mesh></geometry>'
            '</visual>')
    world = load_world(_write_world(tmp_path, _link_model("cube", body)))
    assert world.skipped == (
        "mesh 'cube::l::c' (cube.dae: a Collada file without geometry; replaced by the link's "
        "visual mesh 'v')",)
    (shape,) = world.shapes
    assert shape.kind == "mesh" and shape.mesh_path == tmp_path / "cube.stl"


def test_the_same_missing_mesh_in_many_includes_is_one_report(tmp_path, monkeypatch,
                                                             no_model_path):
    model_dir = tmp_path / "models" / "rack"
    model_dir.mkdir(parents=True)
    (model_dir / "model.sdf").write_text(
        '<sdf version="1.7"><model name="rack"><static>true</static><link name="l">'
        '<collision name="c"><geometry><mesh><uri>model://rack/meshes/rack.dae</uri></mesh>'
        '</geometry></collision></link></model></sdf>')
    monkeypatch.setenv("GAZEBO_MODEL_PATH", str(tmp_path / "models"))
    includes = "".join(f"<include><uri>model://rack</uri><name>rack_{i}</name>"
                       f"<pose>{i} 0 0 0 0 0</pose></include>" for i in range(5))
    world = load_world(_write_world(tmp_path, includes))
    assert world.skipped == (
        "mesh 'rack_0::l::c' and 4 more (model://rack/meshes/rack.dae not found (looked in: "
        f"{tmp_path / 'models'}, {model_dir}, {model_dir / 'models'}, "
        f"{Path.home()}/.gazebo/models))",)
    assert world.shapes == ()


# --------------------------------------------------------------------------- bundled worlds


@pytest.fixture(scope="module")
def warehouse() -> World:
    return load_world("warehouse_slab")


@pytest.fixture(scope="module")
def aisles() -> World:
    return load_world("narrow_aisles")


def _extent(world: World, prefix: str) -> tuple[np.ndarray, np.ndarray]:
    """x, y [m] lower and upper corners of the obstacle outlines whose names start so."""
    shapes = [s for s in obstacle_shapes(world) if s.name.startswith(prefix)]
    assert shapes, prefix
    pts = np.vstack(world_polygons(World("w", world.source, tuple(shapes))))
    return pts.min(axis=0), pts.max(axis=0)


def test_warehouse_slab_loads_without_skips_and_its_slab_is_floor(warehouse):
    assert warehouse.skipped == () and warehouse.floor == ()
    assert len(warehouse.shapes) == 34
    assert [s.name for s in floor_shapes(warehouse)] == [
        "floor_slab::slab::collision", "loading_plate::plate::collision"]
    assert len(obstacle_shapes(warehouse)) == 32
    slab = _shape(warehouse, "floor_slab::slab::collision")
    assert shape_z_extent(slab) == pytest.approx((-0.08, 0.02))
    pallet = _shape(warehouse, "pallet_low::pallet::collision")
    assert shape_z_extent(pallet) == pytest.approx((0.02, 0.12))
    assert pallet in obstacle_shapes(warehouse)


@pytest.mark.parametrize(("prefix", "lo", "hi"), [
    # included shelves posed relative_to the row's frame
    ("rack_row_north::shelf_1::", (-7.6, 3.1), (-4.6, 3.9)),
    ("rack_row_north::shelf_2::", (-4.4, 3.1), (-1.4, 3.9)),
    # the south row is posed relative_to the north row (5 m south)
    ("rack_row_south::shelf_1::", (-7.6, -1.9), (-4.6, -1.1)),
    # the inline nested shelf, turned half a turn
    ("rack_row_south::shelf_2::", (-4.4, -1.9), (-1.4, -1.1)),
    ("hall::", (-10.2, -7.2), (10.2, 7.2)),
    ("pallet_low::", (-9.4, -6.6), (-8.2, -5.8)),
])
def test_warehouse_slab_shelves_stand_where_the_world_says(warehouse, prefix, lo, hi):
    got_lo, got_hi = _extent(warehouse, prefix)
    np.testing.assert_allclose(got_lo, lo, atol=1e-6)
    np.testing.assert_allclose(got_hi, hi, atol=1e-6)


def test_warehouse_slab_shelves_have_several_links_each(warehouse):
    names = [s.name for s in warehouse.shapes if s.name.startswith("rack_row_north::shelf_1::")]
    assert {n.split("::")[2] for n in names} == {"bottom_bay", "uprights", "decks"}
    assert len(names) == 7


def test_narrow_aisles_loads_state_poses_and_ground_plane(aisles):
    assert aisles.skipped == ()
    assert aisles.floor == ("ground_plane::link::collision",)
    # the beams at 2.6 m are above the band; everything else is an obstacle
    assert len(aisles.shapes) == 36 and len(obstacle_shapes(aisles)) == 32
    # rack_3 is declared at y = 0.5; the saved <state> puts it at y = 1.0
    assert _shape(aisles, "rack_3::bottom_beam::collision").pose[1] == pytest.approx(1.0)


@pytest.mark.parametrize(("rack", "x"), [(1, -5.1), (2, -1.7), (3, 1.7), (4, 5.1)])
def test_narrow_aisles_racks_leave_2_4_m_aisles(aisles, rack, x):
    lo, hi = _extent(aisles, f"rack_{rack}::")
    np.testing.assert_allclose(lo, [x - 0.5, -3.0], atol=1e-4)
    np.testing.assert_allclose(hi, [x + 0.5, 5.0], atol=1e-4)
    walls_lo, walls_hi = _extent(aisles, "store_walls::")
    # interior x in [-8, 8]: the first and last aisle are 2.4 m wide as well
    assert -5.6 - (-8.0) == pytest.approx(2.4) and walls_lo[0] == pytest.approx(-8.15)
