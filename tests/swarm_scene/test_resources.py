"""Resource URIs as ROS 2 and Gazebo resolve them: package:// through the ament index and
ROS_PACKAGE_PATH, model:// through the model path, and xacro's $(find pkg) through both."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from swarm_scene.resources import (
    MODEL_PATH_VARS,
    RESOURCE_PATH_VARS,
    ament_index_with_ros_package_path,
    describe,
    package_share,
    resolve,
)

DATA = Path(__file__).resolve().parents[1] / "data"


@pytest.fixture
def clean_env(monkeypatch):
    for var in (*MODEL_PATH_VARS, *RESOURCE_PATH_VARS, "AMENT_PREFIX_PATH", "ROS_PACKAGE_PATH"):
        monkeypatch.delenv(var, raising=False)
    return monkeypatch


def ament_prefix(root: Path, package: str) -> Path:
    """An install prefix as colcon makes it: the marker and share/<package>."""
    (root / "share" / "ament_index" / "resource_index" / "packages").mkdir(parents=True)
    (root / "share" / "ament_index" / "resource_index" / "packages" / package).write_text("")
    (root / "share" / package / "meshes").mkdir(parents=True)
    return root


def source_package(root: Path, directory: str, package: str) -> Path:
    """A source package under a ROS_PACKAGE_PATH root: its package.xml names it."""
    pkg = root / directory
    (pkg / "meshes").mkdir(parents=True)
    (pkg / "package.xml").write_text(f"<package format='3'><name>{package}</name></package>")
    return pkg


def test_package_uri_through_the_ament_index(tmp_path, clean_env):
    prefix = ament_prefix(tmp_path / "install", "shelf_description")
    shutil.copy(DATA / "world_cube.stl", prefix / "share" / "shelf_description" / "meshes")
    clean_env.setenv("AMENT_PREFIX_PATH", f"{tmp_path / 'other'}:{prefix}")
    path, looked = resolve("package://shelf_description/meshes/world_cube.stl", tmp_path)
    assert path == prefix / "share" / "shelf_description" / "meshes" / "world_cube.stl"
    assert looked[0] == str(tmp_path / "other" / "share" / "shelf_description")


def test_package_uri_through_ros_package_path_by_package_xml(tmp_path, clean_env):
    pkg = source_package(tmp_path / "src", "shelf_desc_repo", "shelf_description")
    shutil.copy(DATA / "world_cube.stl", pkg / "meshes")
    clean_env.setenv("ROS_PACKAGE_PATH", str(tmp_path / "src"))
    assert package_share("shelf_description")[0] == pkg
    path, _ = resolve("package://shelf_description/meshes/world_cube.stl", tmp_path)
    assert path == pkg / "meshes" / "world_cube.stl"


def test_model_uri_through_the_model_path_then_the_worlds_directory(tmp_path, clean_env):
    (tmp_path / "gz" / "crate").mkdir(parents=True)
    (tmp_path / "world" / "models" / "crate").mkdir(parents=True)
    assert resolve("model://crate", tmp_path / "world")[0] == tmp_path / "world/models/crate"
    clean_env.setenv("GZ_SIM_RESOURCE_PATH", str(tmp_path / "gz"))
    assert resolve("model://crate", tmp_path / "world")[0] == tmp_path / "gz" / "crate"


def test_an_unresolved_uri_names_where_it_looked(tmp_path, clean_env):
    clean_env.setenv("AMENT_PREFIX_PATH", str(tmp_path / "install"))
    clean_env.setenv("ROS_PACKAGE_PATH", str(tmp_path / "src"))
    path, looked = resolve("package://nowhere_pkg/meshes/a.dae", tmp_path)
    assert path is None
    text = describe("package://nowhere_pkg/meshes/a.dae", looked)
    assert text.startswith("package://nowhere_pkg/meshes/a.dae not found (looked in: ")
    assert str(tmp_path / "install" / "share" / "nowhere_pkg") in text
    assert f"{tmp_path / 'src'} (ROS_PACKAGE_PATH)" in text
    assert "and 1 more" in text  # ~/.gazebo/models and the world's own places follow
    assert "not resolvable offline" in describe("https://fuel/x.dae",
                                                resolve("https://fuel/x.dae", tmp_path)[1])


def _mesh_under(root: Path) -> Path:
    """``root/models/crate/meshes/world_cube.stl``, as AWS RoboMaker's worlds lay meshes out."""
    (root / "models" / "crate" / "meshes").mkdir(parents=True)
    return Path(shutil.copy(DATA / "world_cube.stl", root / "models" / "crate" / "meshes"))


RELATIVE = "file://models/crate/meshes/world_cube.stl"


def test_a_relative_file_uri_is_found_in_the_working_directory_first(tmp_path, clean_env):
    here, world_dir = tmp_path / "here", tmp_path / "world"
    in_cwd, beside = _mesh_under(here), _mesh_under(world_dir)
    clean_env.chdir(here)
    assert resolve(RELATIVE, world_dir)[0] == in_cwd
    clean_env.chdir(tmp_path)  # not here: beside the referring file
    assert resolve(RELATIVE, world_dir)[0] == beside
    # a plain relative path prefers the referring file's directory
    clean_env.chdir(here)
    assert resolve("models/crate/meshes/world_cube.stl", world_dir)[0] == beside


@pytest.mark.parametrize("var", RESOURCE_PATH_VARS)
def test_a_relative_file_uri_is_found_on_the_resource_path(tmp_path, clean_env, var):
    share = tmp_path / "share" / "aws_small_warehouse"
    expected = _mesh_under(share)
    clean_env.chdir(tmp_path)
    clean_env.setenv(var, f"{tmp_path / 'other'}:{share}")
    path, looked = resolve(RELATIVE, tmp_path / "worlds")
    assert path == expected
    assert looked == [str(tmp_path), str(tmp_path / "worlds"), f"{tmp_path / 'other'} ({var})",
                      f"{share} ({var})"]


def test_an_unresolved_relative_file_uri_names_where_it_looked(tmp_path, clean_env):
    clean_env.chdir(tmp_path)
    clean_env.setenv("GAZEBO_RESOURCE_PATH", str(tmp_path / "gz"))
    path, looked = resolve(RELATIVE, tmp_path / "worlds")
    assert path is None
    assert describe(RELATIVE, looked) == (
        f"{RELATIVE} not found (looked in: {tmp_path}, {tmp_path / 'worlds'}, "
        f"{tmp_path / 'gz'} (GAZEBO_RESOURCE_PATH))")
    absolute = f"file://{tmp_path}/nothing.stl"
    assert resolve(absolute, tmp_path) == (None, [])  # an absolute path names its one place


def test_a_world_mesh_by_package_uri_loads(tmp_path, clean_env):
    from swarm_scene.world import load_world, world_polygons

    prefix = ament_prefix(tmp_path / "install", "crate_description")
    shutil.copy(DATA / "world_cube.stl", prefix / "share" / "crate_description" / "meshes")
    clean_env.setenv("AMENT_PREFIX_PATH", str(prefix))
    world = tmp_path / "w.world"
    world.write_text(
        '<?xml version="1.0"?><sdf version="1.6"><world name="w"><model name="crate">'
        "<static>true</static><pose>2 0 0 0 0 0</pose><link name='l'><collision name='c'>"
        "<geometry><mesh><uri>package://crate_description/meshes/world_cube.stl</uri></mesh>"
        "</geometry></collision></link></model></world></sdf>")
    loaded = load_world(world)
    assert loaded.skipped == () and len(world_polygons(loaded)) == 1


@pytest.mark.parametrize("how", ["ament", "ros_package_path"])
def test_xacro_find_resolves_through_both(tmp_path, clean_env, how):
    from swarm_scene.robot_model import load_robot

    body = (DATA.parent.parent / "robots" / "turtlebot3_waffle.urdf.xacro").read_text()
    if how == "ament":
        pkg = ament_prefix(tmp_path / "install", "my_robot_description") / "share" / \
            "my_robot_description"
        clean_env.setenv("AMENT_PREFIX_PATH", str(tmp_path / "install"))
    else:
        pkg = source_package(tmp_path / "src", "my_robot_description", "my_robot_description")
        clean_env.setenv("ROS_PACKAGE_PATH", str(tmp_path / "src"))
    (pkg / "urdf").mkdir()
    (pkg / "urdf" / "body.urdf.xacro").write_text(body)
    top = tmp_path / "my_robot.urdf.xacro"
    top.write_text('<?xml version="1.0"?><robot name="my_robot" '
                   'xmlns:xacro="http://ros.org/wiki/xacro">'
                   '<xacro:include filename="$(find my_robot_description)/urdf/body.urdf.xacro"/>'
                   "</robot>")
    shutil.copy(DATA.parent.parent / "params" / "robots" / "turtlebot3_waffle.yaml",
                tmp_path / "my_robot.yaml")
    model = load_robot(top)
    assert model.radius > 0.1
    with ament_index_with_ros_package_path():
        pass  # nothing left behind
    assert ("AMENT_PREFIX_PATH" in __import__("os").environ) == (how == "ament")
