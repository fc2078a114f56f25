"""Where bundled data lives, and which map a world gets by default (one rule for swarm-up and
swarm-sim)."""

import shutil

from swarm_common import paths


def test_a_bundled_world_gets_its_bundled_map(monkeypatch):
    expected = paths.MAPS_DIR / "slim_blockage.yaml"
    assert paths.default_map_for(paths.WORLDS_DIR / "slim_blockage.world") == expected
    monkeypatch.chdir(paths.ROOT)  # a relative path to the bundled file is the bundled world
    assert paths.default_map_for("worlds/slim_blockage.world") == expected
    assert paths.default_map_for(paths.WORLDS_DIR / "factory_floor.world") == (
        paths.MAPS_DIR / "factory_floor.yaml")


def test_a_world_by_path_never_gets_a_bundled_map_that_shares_its_name(tmp_path):
    copy = tmp_path / "slim_blockage.world"
    shutil.copy(paths.WORLDS_DIR / "slim_blockage.world", copy)
    assert paths.default_map_for(copy) is None
    assert paths.default_map_for(tmp_path / "worlds" / "empty.world") is None


def test_a_bundled_world_without_a_map_gets_none(tmp_path, monkeypatch):
    monkeypatch.setattr(paths, "MAPS_DIR", tmp_path)
    assert paths.default_map_for(paths.WORLDS_DIR / "slim_blockage.world") is None
