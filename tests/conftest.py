"""Shared test fixtures.

Every test session claims its own ``ROS_DOMAIN_ID`` (an flock on ``/tmp/swarm_wb_domain_<id>.lock``
held for the whole session) and sets ``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, so two test runs
on one machine never hear each other.  Processes started by tests inherit both.  The session
removes orphaned Fast DDS shared-memory files before it starts, the ones its own processes left
behind before each test that starts ROS participants, and when it ends.
"""

from __future__ import annotations

import fcntl
import os
from pathlib import Path

import pytest

from swarm_up import shm

_DOMAIN_LOCK = None
_SHM_BEFORE: frozenset[str] = frozenset()


def _claim_domain_id() -> int:
    global _DOMAIN_LOCK
    for domain in range(101, 200):
        fh = open(f"/tmp/swarm_wb_domain_{domain}.lock", "w")  # noqa: SIM115 - held for the session
        try:
            fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            fh.close()
            continue
        _DOMAIN_LOCK = fh
        return domain  # the lock file stays open until pytest_unconfigure
    raise RuntimeError("no free ROS_DOMAIN_ID in 101..199 for this test session")


def pytest_configure(config):
    # an xdist worker (pytest -n) claims a domain of its own, not its controller's
    if "SWARM_WB_TEST_DOMAIN" not in os.environ or "PYTEST_XDIST_WORKER" in os.environ:
        os.environ["SWARM_WB_TEST_DOMAIN"] = str(_claim_domain_id())
    os.environ["ROS_DOMAIN_ID"] = os.environ["SWARM_WB_TEST_DOMAIN"]
    os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    # Orphans of killed processes (no live process holds them) make Fast DDS print
    # "Failed init_port ... open_and_lock_file failed" into every node's output: remove them.
    global _SHM_BEFORE
    shm.clean_stale(frozenset(), min_age_s=5.0)
    _SHM_BEFORE = shm.snapshot()
    # Compile the navigator's numba kernels now (about 15 s on a fresh clone; a cache load
    # after), not inside the first test that starts a navigator, whose wall-clock waits would
    # count the compilation.
    from swarm_nav import jit

    jit.warm_up()
    # Build tf2_msgs and simulation_interfaces (about 80 s once; swarm_ros/built_interfaces.py)
    # now, for the same reason; a worker finds them built (or waits on the build's lock).
    from swarm_ros.built_interfaces import ensure

    ensure()


SLOW_TIERS = ("node", "e2e", "slow")


ROS_TIERS = ("node", "e2e")


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item):
    """Before a test that starts ROS participants (and its fixtures): remove the Fast DDS files
    this session's killed processes left that no live process uses. The session keeps one
    ``ROS_DOMAIN_ID``, so later participants take the same port numbers: after processes of
    the domain were killed, a run's commander was seen to hear nothing of its navigator for
    120 s (docs/HISTORY.md, "A commander deaf to its navigator"). Files there before the
    session, and those of live processes, are kept."""
    if not any(item.get_closest_marker(m) for m in ROS_TIERS):
        return
    if shm.snapshot() - _SHM_BEFORE:
        shm.clean_stale(_SHM_BEFORE, min_age_s=1.0, ignore_pids=frozenset({os.getpid()}))


def pytest_collection_modifyitems(config, items):
    """Mark ``quick`` every test that is neither ``node``, ``e2e`` nor ``slow``: the inner loop's
    tier (``pytest -m quick``, a few minutes; the README's developer section). Every ``node``
    and ``e2e`` test goes to one xdist group, so that with ``-n 2 --dist loadgroup`` (the
    suite's default, pyproject.toml) they run one after the other in one worker, as without
    xdist, while the other worker takes the tests that start no process."""
    for item in items:
        if not any(item.get_closest_marker(m) for m in SLOW_TIERS):
            item.add_marker(pytest.mark.quick)
        if any(item.get_closest_marker(m) for m in ROS_TIERS):
            item.add_marker(pytest.mark.xdist_group("ros"))


@pytest.fixture(scope="session")
def repo_root() -> Path:
    return Path(__file__).resolve().parents[1]


@pytest.fixture
def swarm(tmp_path):
    """``swarm(n, world=..., poi=...)`` starts a swarm of ``n`` robots (the simulator, one
    navigator group and a probe node: :class:`tests.swarm_nav.test_node_behaviour.Swarm`);
    every swarm is stopped at the end."""
    from tests.swarm_nav.test_node_behaviour import Swarm

    made = []

    def make(n: int, **kwargs):
        sw = Swarm(tmp_path / f"run{len(made)}", n, **kwargs)
        sw.dir.mkdir()
        made.append(sw)
        return sw.launch()

    try:
        yield make
    finally:
        for sw in made:
            sw.close()


def pytest_unconfigure(config):
    global _DOMAIN_LOCK
    # This process's own participants (the tests' probe nodes) keep the ports of dead peers
    # mapped: they do not count, as in swarm-up (a listener's lock still does). Without this, a
    # CI run once left four such ports behind (2026-11-25).
    shm.clean_stale(_SHM_BEFORE, min_age_s=0.0, ignore_pids=frozenset({os.getpid()}))
    if _DOMAIN_LOCK is not None:
        _DOMAIN_LOCK.close()
        _DOMAIN_LOCK = None
