"""Where the bundled data lives (the repository root of an editable install)."""

from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
WORLDS_DIR = ROOT / "worlds"
MAPS_DIR = ROOT / "maps"
ROBOTS_DIR = ROOT / "robots"
PARAMS_DIR = ROOT / "params"
ROBOT_PARAMS_DIR = PARAMS_DIR / "robots"
# Fast DDS profiles without shared memory (swarm_up.children.shm_free_env).
FASTDDS_UDP_ONLY_PROFILE = PARAMS_DIR / "fastdds_udp_only.xml"
FASTDDS_UDP_LOOPBACK_PROFILE = PARAMS_DIR / "fastdds_udp_loopback.xml"


def find_named(name: str, directory: Path, suffixes) -> Path | None:
    """The absolute path of ``<directory>/<name><suffix>`` for the first of ``suffixes`` that
    exists as a file, else None (a world or robot given by name)."""
    for suffix in suffixes:
        candidate = directory / f"{name}{suffix}"
        if candidate.is_file():
            return candidate.resolve()
    return None


def default_map_for(world_path: str | Path) -> Path | None:
    """The bundled map of a bundled world: ``maps/<stem>.yaml`` for a world under ``worlds/``.

    ``swarm-up`` and ``swarm-sim`` both take their default map from here.  A world given by a
    path outside ``worlds/`` gets None (rasterise the map from the world itself), never a bundled
    map that merely shares its name.

    Args:
        world_path: the world file (a resolved or relative path).

    Returns:
        The map YAML, or None when the world is not bundled or has no bundled map.
    """
    world_path = Path(world_path).resolve()
    if world_path.parent != WORLDS_DIR.resolve():
        return None
    candidate = MAPS_DIR / f"{world_path.stem}.yaml"
    return candidate if candidate.is_file() else None
