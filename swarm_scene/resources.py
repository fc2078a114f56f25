"""Where a ROS or Gazebo resource URI points: ``package://``, ``model://``, ``file://``, paths.

Resolved as ROS 2 and Gazebo resolve them, for the worlds' meshes and includes
(:mod:`swarm_scene.world`), the robots' meshes (:mod:`swarm_scene.robot_model`) and xacro's
``$(find pkg)`` (:func:`ament_index_with_ros_package_path`):

- ``package://<pkg>/<rest>``: ``<pkg>``'s share directory from the ament index (every prefix of
  ``AMENT_PREFIX_PATH`` that has ``share/ament_index/resource_index/packages/<pkg>``, as
  ``ament_index_python.get_package_share_directory`` finds it; a prefix with ``share/<pkg>`` but
  no marker counts too, as colcon's merged installs of old have it), then ``ROS_PACKAGE_PATH``
  (a directory ``<pkg>`` of one of its roots, or a directory directly under a root whose
  ``package.xml`` names ``<pkg>``), then Gazebo's model path as for ``model://`` (Gazebo Sim
  resolves ``package://`` through its resource path too).
- ``model://<model>/<rest>``: the first of ``GZ_SIM_RESOURCE_PATH``, ``IGN_GAZEBO_RESOURCE_PATH``,
  ``GAZEBO_MODEL_PATH``, ``SDF_PATH`` (each a ``:``-list), the world's directory, its
  ``models/``, ``~/.gazebo/models`` that has ``<model>/<rest>``.
- ``file://<path>`` and a plain path: an absolute one names itself; a relative one is looked
  for as Gazebo does (gazebo-classic's ``SystemPaths::FindFileURI``, gz-sim's resource path):
  for ``file://`` in the working directory first, then the referring file's directory; for a
  plain path the referring file's directory first, then the working directory; then under each
  entry of ``GAZEBO_RESOURCE_PATH`` and of ``GZ_SIM_RESOURCE_PATH`` (ROS packages export their
  share directory into the first as ``gazebo_media_path``). AWS RoboMaker's worlds name their
  meshes ``file://models/<model>/meshes/<mesh>.DAE``, meant for a run from the repository's
  root or with it on one of those paths.
- Anything else with ``://`` (``http(s)://``, Fuel) is not resolvable offline.

:func:`resolve` returns where it looked, so an unresolved URI can be named once with the places
searched.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from pathlib import Path

MODEL_PATH_VARS = ("GZ_SIM_RESOURCE_PATH", "IGN_GAZEBO_RESOURCE_PATH", "GAZEBO_MODEL_PATH",
                   "SDF_PATH")
RESOURCE_PATH_VARS = ("GAZEBO_RESOURCE_PATH", "GZ_SIM_RESOURCE_PATH")
"""Where a relative ``file://`` URI or path is looked for after the working directory and the
referring file's directory (module doc)."""
_MARKERS = Path("share") / "ament_index" / "resource_index" / "packages"


def _env_dirs(var: str) -> list[Path]:
    return [Path(p) for p in os.environ.get(var, "").split(os.pathsep) if p]


def model_search_path(base: Path) -> list[Path]:
    """The directories ``model://`` looks in, in order (module doc)."""
    dirs = [d for var in MODEL_PATH_VARS for d in _env_dirs(var)]
    return dirs + [base, base / "models", Path.home() / ".gazebo" / "models"]


def _package_xml_name(path: Path) -> str | None:
    try:
        return (ET.parse(path).getroot().findtext("name") or "").strip() or None
    except (ET.ParseError, OSError):
        return None


def package_share(package: str) -> tuple[Path | None, list[str]]:
    """A package's directory: from the ament index, else ``ROS_PACKAGE_PATH`` (module doc).

    Returns:
        ``(directory or None, the places looked in)``.
    """
    looked = []
    for prefix in _env_dirs("AMENT_PREFIX_PATH"):
        share = prefix / "share" / package
        looked.append(str(share))
        if share.is_dir():
            return share, looked
    for root in _env_dirs("ROS_PACKAGE_PATH"):
        looked.append(f"{root} (ROS_PACKAGE_PATH)")
        if (root / package).is_dir():
            return root / package, looked
        if root.is_dir():
            for child in sorted(root.iterdir()):
                xml = child / "package.xml"
                if xml.is_file() and _package_xml_name(xml) == package:
                    return child, looked
    if not looked:
        looked.append("AMENT_PREFIX_PATH and ROS_PACKAGE_PATH (both unset)")
    return None, looked


def resolve(uri: str, base: Path) -> tuple[Path | None, list[str]]:
    """The file or directory a URI names (module doc), and where it looked.

    Args:
        uri: ``package://``, ``model://``, ``file://``, or a path.
        base: the directory of the file that refers to it (a world, a robot description).

    Returns:
        ``(path or None, places looked in)``; the path exists when not None; an absolute path
        or ``file://`` URI names its one place itself (no places listed).
    """
    if uri.startswith("package://"):
        package, _, rest = uri[len("package://"):].partition("/")
        share, looked = package_share(package)
        if share is not None and (share / rest).exists():
            return share / rest, looked
        model, more = _model(f"{package}/{rest}", base)
        return model, looked + more
    if uri.startswith("model://"):
        return _model(uri[len("model://"):], base)
    if uri.startswith("file://"):
        return _file(Path(uri[len("file://"):]), [Path.cwd(), base])
    if "://" in uri:
        return None, [f"nowhere: {uri.split('://', 1)[0]}:// is not resolvable offline"]
    return _file(Path(uri).expanduser(), [base, Path.cwd()])


def _file(path: Path, first: list[Path]) -> tuple[Path | None, list[str]]:
    """An absolute path names itself; a relative one is looked for under ``first``, then each
    entry of :data:`RESOURCE_PATH_VARS` (module doc)."""
    if path.is_absolute():
        return (path if path.exists() else None), []
    looked = []
    roots = [(str(d), d) for d in first]
    roots += [(f"{d} ({var})", d) for var in RESOURCE_PATH_VARS for d in _env_dirs(var)]
    for name, root in roots:
        looked.append(name)
        if (root / path).exists():
            return root / path, looked
    return None, looked


def _model(rest: str, base: Path) -> tuple[Path | None, list[str]]:
    looked = []
    for d in model_search_path(base):
        looked.append(str(d))
        if (d / rest).exists():
            return d / rest, looked
    return None, looked


def describe(uri: str, looked: list[str], limit: int = 4) -> str:
    """``"<uri> not found (looked in: a, b, c, ... and N more)"``, for a one-line report."""
    shown = ", ".join(looked[:limit]) + (f" and {len(looked) - limit} more"
                                         if len(looked) > limit else "")
    return f"{uri} not found (looked in: {shown})" if looked else f"{uri} not found"


def ros_package_path_packages() -> dict[str, Path]:
    """Every package of ``ROS_PACKAGE_PATH``: name -> directory (a root that is a package
    itself, or a directory directly under a root with a ``package.xml``); the first wins."""
    out: dict[str, Path] = {}
    for root in _env_dirs("ROS_PACKAGE_PATH"):
        candidates = [root] + (sorted(c for c in root.iterdir() if c.is_dir())
                               if root.is_dir() else [])
        for d in candidates:
            xml = d / "package.xml"
            name = _package_xml_name(xml) if xml.is_file() else None
            if name and name not in out:
                out[name] = d
    return out


@contextlib.contextmanager
def ament_index_with_ros_package_path() -> Iterator[None]:
    """Make xacro's ``$(find pkg)`` see the packages of ``ROS_PACKAGE_PATH`` too.

    xacro resolves ``$(find pkg)`` through the ament index only
    (``ament_index_python.get_package_share_directory``). Every package of ``ROS_PACKAGE_PATH``
    (:func:`ros_package_path_packages`) that the index lacks gets, for the duration, a marker
    and a ``share/<pkg>`` link in a temporary prefix put after ``AMENT_PREFIX_PATH``'s own
    (the index wins), removed after.
    """
    indexed = {m.name for prefix in _env_dirs("AMENT_PREFIX_PATH")
               if (prefix / _MARKERS).is_dir() for m in (prefix / _MARKERS).iterdir()}
    missing = {k: v for k, v in ros_package_path_packages().items() if k not in indexed}
    if not missing:
        yield
        return
    old = os.environ.get("AMENT_PREFIX_PATH")
    with tempfile.TemporaryDirectory(prefix="swarm_ament_") as tmp:
        prefix = Path(tmp)
        (prefix / _MARKERS).mkdir(parents=True)
        for pkg, share in missing.items():
            (prefix / _MARKERS / pkg).write_text("")
            (prefix / "share" / pkg).symlink_to(share.resolve(), target_is_directory=True)
        os.environ["AMENT_PREFIX_PATH"] = os.pathsep.join(p for p in (old, str(prefix)) if p)
        try:
            yield
        finally:
            if old is None:
                os.environ.pop("AMENT_PREFIX_PATH", None)
            else:
                os.environ["AMENT_PREFIX_PATH"] = old
