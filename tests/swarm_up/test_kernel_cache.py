"""swarm-up compiles the navigator's kernels first when numba's cache is missing or stale."""

import os
from pathlib import Path

from swarm_up.orchestrator import kernels_cached


def _touch(path: Path, mtime: float) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("x")
    os.utime(path, (mtime, mtime))


def test_a_kernel_source_newer_than_its_cache_is_not_cached(tmp_path: Path):
    _touch(tmp_path / "dwa_kernels.py", 1000.0)
    _touch(tmp_path / "planner_kernels.py", 1000.0)
    _touch(tmp_path / "node.py", 5000.0)  # not a kernel module: ignored
    assert not kernels_cached(tmp_path)  # no cache at all
    _touch(tmp_path / "__pycache__" / "dwa_kernels.choose-556.py311.nbi", 2000.0)
    assert not kernels_cached(tmp_path)  # planner_kernels has none
    _touch(tmp_path / "__pycache__" / "planner_kernels.astar-10.py311.nbi", 2000.0)
    assert kernels_cached(tmp_path)
    # a checkout rewrites the source: the index left from before is stale
    _touch(tmp_path / "dwa_kernels.py", 3000.0)
    assert not kernels_cached(tmp_path)
    # numba compiles again and writes a new index beside the stale one of an old line number
    _touch(tmp_path / "__pycache__" / "dwa_kernels.choose-560.py311.nbi", 3001.0)
    assert kernels_cached(tmp_path)


def test_the_installed_package_is_cached_after_the_test_session_warmed_it_up():
    import swarm_nav

    # tests/conftest.py ran swarm_nav.jit.warm_up(): every kernel module has a fresh index
    assert kernels_cached(Path(swarm_nav.__file__).parent)
