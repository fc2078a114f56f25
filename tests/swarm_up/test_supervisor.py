"""Supervision with dummy children: restart, stop within 5 s, and the shared-memory cleaner."""

import fcntl
import mmap
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

from swarm_up import shm
from swarm_up.supervisor import ChildSpec, ResourceSampler, Supervisor

# Handles SIGINT as Python does by default even when started with SIGINT ignored (a test run
# launched as `nohup ... &` inherits that, and the child then only dies of SIGTERM).
# It says "ready" once its handler is in place: a SIGINT that comes while the interpreter still
# starts ends it with code 1 (seen once in CI, under load), not -SIGINT.
SLEEPER = (sys.executable, "-c", "import signal, time; "
           "signal.signal(signal.SIGINT, signal.default_int_handler); "
           "print('ready', flush=True); time.sleep(100)")
# ignores SIGINT and SIGTERM, and starts a grandchild in its group that does the same
STUBBORN = (
    sys.executable,
    "-c",
    "import signal, subprocess, sys, time\n"
    "signal.signal(signal.SIGINT, signal.SIG_IGN); signal.signal(signal.SIGTERM, signal.SIG_IGN)\n"
    "subprocess.Popen([sys.executable, '-c', 'import signal, time; "
    "signal.signal(signal.SIGINT, signal.SIG_IGN); signal.signal(signal.SIGTERM, signal.SIG_IGN); "
    "print(\"grandchild\", flush=True); time.sleep(100)'])\n"
    "time.sleep(100)",
)


@pytest.fixture
def sup():
    s = Supervisor()
    yield s
    s.stop()


def _spec(tmp_path, name, argv=SLEEPER, **kw):
    return ChildSpec(name, tuple(argv), tmp_path / "logs" / f"{name}.log", **kw)


def _wait(pred, timeout):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(0.02)
    return pred()


def test_killed_child_restarts_within_2s(sup, tmp_path):
    seen = []
    sup.on_restart = seen.append
    sup.start(_spec(tmp_path, "nav_a", robots=("a",)))
    sup.start(_spec(tmp_path, "nav_b", robots=("b",)))
    old_pid, other_pid = sup.pid("nav_a"), sup.pid("nav_b")
    os.kill(old_pid, signal.SIGKILL)
    t_kill = time.monotonic()
    restarted_at = None
    while time.monotonic() - t_kill < 3.0:
        sup.poll()  # the orchestrator polls at 10 Hz
        if sup.pid("nav_a") != old_pid and sup.alive("nav_a"):
            restarted_at = time.monotonic()
            break
        time.sleep(0.1)
    assert restarted_at is not None and restarted_at - t_kill < 2.0
    assert sup.restarts == 1 and sup.children["nav_a"].restarts == 1
    assert [(e.name, e.code, e.restarted) for e in seen] == [("nav_a", -signal.SIGKILL, True)]
    assert sup.pid("nav_b") == other_pid and sup.alive("nav_b")  # the others are not disturbed
    log = (tmp_path / "logs" / "nav_a.log").read_text()
    assert "restart 1 of nav_a" in log


def test_non_restartable_child_is_reported(sup, tmp_path):
    sup.start(_spec(tmp_path, "sim", (sys.executable, "-c", "import sys; sys.exit(3)"),
                    kind="sim", restart=False))
    assert _wait(lambda: not sup.alive("sim"), 5.0)
    exits = sup.poll()
    assert [(e.name, e.code, e.restarted) for e in exits] == [("sim", 3, False)]
    assert sup.restarts == 0
    assert sup.poll() == []  # reported once


@pytest.mark.parametrize("code", [0, 2])
def test_done_or_bad_input_is_not_restarted(sup, tmp_path, code):
    sup.start(_spec(tmp_path, "cmd_a", (sys.executable, "-c", f"import sys; sys.exit({code})")))
    assert _wait(lambda: not sup.alive("cmd_a"), 5.0)
    exits = sup.poll()
    assert [(e.code, e.restarted) for e in exits] == [(code, False)]
    assert sup.restarts == 0


def test_fast_crash_loop_is_given_up(sup, tmp_path):
    sup.max_fast_crashes = 3
    sup.start(_spec(tmp_path, "nav_x", (sys.executable, "-c", "import sys; sys.exit(1)")))
    gave_up = []
    deadline = time.monotonic() + 10.0
    while not gave_up and time.monotonic() < deadline:
        gave_up = [e for e in sup.poll() if e.gave_up]
        time.sleep(0.05)
    assert gave_up and sup.children["nav_x"].given_up
    assert sup.restarts == 2


def test_stop_ends_everything_within_5s(tmp_path):
    sup = Supervisor()
    sup.start(_spec(tmp_path, "sim", kind="sim", restart=False))
    for i in range(3):
        sup.start(_spec(tmp_path, f"nav_{i}"))
    sup.start(_spec(tmp_path, "stubborn", STUBBORN))
    assert _wait(lambda: "grandchild" in (tmp_path / "logs" / "stubborn.log").read_text(), 10.0)
    for i in range(3):  # each sleeper's SIGINT handler is in place
        assert _wait(lambda i=i: "ready" in (tmp_path / "logs" / f"nav_{i}.log").read_text(),
                     10.0)
    pids = [sup.pid(n) for n in sup.children]
    group_members = [p for p in psutil.process_iter(["pid"])
                     if _pgid(p.pid) in pids]
    assert len(group_members) >= 6  # 5 children + the grandchild
    t0 = time.monotonic()
    codes = sup.stop()
    elapsed = time.monotonic() - t0
    assert elapsed < 5.0
    assert codes["nav_0"] == -signal.SIGINT
    assert codes["stubborn"] == -signal.SIGKILL
    assert _wait(lambda: not any(p.is_running() and p.status() != psutil.STATUS_ZOMBIE
                                 for p in group_members), 1.0)
    assert sup.poll() == [] or all(not e.restarted for e in sup.poll())


def _pgid(pid):
    try:
        return os.getpgid(pid)
    except ProcessLookupError:
        return None


def test_no_restart_while_stopping(tmp_path):
    sup = Supervisor()
    sup.start(_spec(tmp_path, "nav_a"))
    sup.stop()
    assert all(not e.restarted for e in sup.poll())
    assert not sup.alive("nav_a") and sup.restarts == 0


def test_resource_sampler(sup, tmp_path):
    burn = (sys.executable, "-c", "import time\nt = time.time()\nwhile time.time() - t < 99: pass")
    sup.start(_spec(tmp_path, "nav_a", burn, robots=("a",)))
    sup.start(_spec(tmp_path, "nav_b", robots=("b",)))
    sup.start(_spec(tmp_path, "sim", kind="sim", restart=False))
    sampler = ResourceSampler(sup, robots=2, period_s=0.2)
    assert sampler.maybe_sample()
    assert not sampler.maybe_sample()  # too soon
    time.sleep(0.6)
    assert sampler.maybe_sample()
    res = sampler.result()
    assert res["cpu_percent"] > 20.0  # one child spins
    assert 1.0 < res["peak_rss_mb_per_robot"] < 200.0
    assert res["sim_peak_rss_mb"] > 1.0


# ------------------------------------------------------------------------ shared-memory cleaner
HOLDER = """
import fcntl, mmap, sys, time
lock = open(sys.argv[1], "rb")
fcntl.flock(lock, fcntl.LOCK_EX)
fh = open(sys.argv[2], "r+b")
mem = mmap.mmap(fh.fileno(), 4096)
fh.close()
print("ready", flush=True)
time.sleep(100)
"""


def _touch(path: Path, size=0):
    path.write_bytes(b"\0" * size)


def test_names_and_groups():
    assert shm.is_fastdds_name("fastrtps_25006958b69b659c")
    assert shm.is_fastdds_name("sem.fastrtps_port7000_mutex")
    assert shm.is_fastdds_name("fast_datasharing_01.0f.aa_0.0.1.3_el")
    assert not shm.is_fastdds_name("lttng-ust-wait-6")
    assert not shm.is_fastdds_name("sem.other")
    assert shm.group_key("fastrtps_port7000_el") == "fastrtps_port7000"
    assert shm.group_key("sem.fastrtps_port7000_mutex") == "fastrtps_port7000"
    assert shm.group_key("fastrtps_25006958b69b659c") == "fastrtps_25006958b69b659c"


def test_cleaner_removes_only_stale_new_files(tmp_path):
    d = tmp_path / "shm"
    d.mkdir()
    # there before the run: never touched, even though nobody uses them
    for name in ("fastrtps_0000000000000001", "fastrtps_0000000000000001_el", "lttng-ust-x"):
        _touch(d / name)
    before = shm.snapshot(d)
    assert before == {"fastrtps_0000000000000001", "fastrtps_0000000000000001_el"}
    # new and stale: a killed participant's segment and a port with its semaphore
    stale = ["fastrtps_aaaaaaaaaaaaaaaa", "fastrtps_aaaaaaaaaaaaaaaa_el", "fastrtps_port7411",
             "fastrtps_port7411_el", "sem.fastrtps_port7411_mutex",
             "fast_datasharing_01.0f.aa.bb_0.0.1.3", "fast_datasharing_01.0f.aa.bb_0.0.1.3_el"]
    for name in stale:
        _touch(d / name, 4096 if not name.endswith(("_el", "_mutex")) else 0)
    # new but alive: one group flock-ed through its _el file, one mmapped only (the fd closed)
    locked = ["fastrtps_bbbbbbbbbbbbbbbb", "fastrtps_bbbbbbbbbbbbbbbb_el"]
    mapped = ["fastrtps_port7413", "fastrtps_port7413_el", "sem.fastrtps_port7413_mutex"]
    for name in locked + mapped:
        _touch(d / name, 4096 if not name.endswith(("_el", "_mutex")) else 0)
    # new, not Fast DDS
    _touch(d / "someone_else")

    holder = subprocess.Popen(
        [sys.executable, "-c", HOLDER, str(d / locked[1]), str(d / mapped[0])],
        stdout=subprocess.PIPE, text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "ready"
        busy = shm.in_use_groups(d)
        assert {"fastrtps_bbbbbbbbbbbbbbbb", "fastrtps_port7413"} <= busy
        assert shm.stale_files(before, d, min_age_s=3600.0) == []  # all too young
        removed = shm.clean_stale(before, d, min_age_s=0.0)
        assert sorted(p.name for p in removed) == sorted(stale)
        left = set(os.listdir(d))
        assert left == {"fastrtps_0000000000000001", "fastrtps_0000000000000001_el",
                        "lttng-ust-x", "someone_else", *locked, *mapped}
    finally:
        holder.kill()
        holder.wait()
        holder.stdout.close()
    # once the holder is gone its groups are stale too
    removed = shm.clean_stale(before, d, min_age_s=0.0)
    assert sorted(p.name for p in removed) == sorted(locked + mapped)


def test_flock_is_seen_in_proc_locks(tmp_path):
    d = tmp_path / "shm"
    d.mkdir()
    _touch(d / "fastrtps_cccccccccccccccc", 4096)
    _touch(d / "fastrtps_cccccccccccccccc_el")
    with open(d / "fastrtps_cccccccccccccccc_el", "rb") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        st = os.stat(d / "fastrtps_cccccccccccccccc_el")
        assert (os.major(st.st_dev), os.minor(st.st_dev), st.st_ino) in shm._locked_inodes()
        assert shm.clean_stale(frozenset(), d, min_age_s=0.0) == []
    assert len(shm.clean_stale(frozenset(), d, min_age_s=0.0)) == 2


def test_clean_after_run_comes_back_for_files_too_young_at_first(tmp_path):
    """A port file a participant re-created in its last moment is spared by the first pass (it
    may be being created by someone) and removed by the second, once old enough; one that is
    still in use stays."""
    d = tmp_path / "shm"
    d.mkdir()
    _touch(d / "fastrtps_port7007", 4096)
    _touch(d / "fastrtps_cccccccccccccccc", 4096)
    _touch(d / "fastrtps_cccccccccccccccc_el")
    assert shm.clean_stale(frozenset(), d, min_age_s=0.3) == []  # both too young
    with open(d / "fastrtps_cccccccccccccccc_el", "rb") as fh:
        fcntl.flock(fh, fcntl.LOCK_EX)
        removed = shm.clean_after_run(frozenset(), d, min_age_s=0.3)
    assert [p.name for p in removed] == ["fastrtps_port7007"]
    assert sorted(os.listdir(d)) == ["fastrtps_cccccccccccccccc", "fastrtps_cccccccccccccccc_el"]


def test_cleaner_on_missing_dir(tmp_path):
    assert shm.snapshot(tmp_path / "nope") == frozenset()
    assert shm.clean_stale(frozenset(), tmp_path / "nope") == []


def test_mmap_in_this_process_is_busy(tmp_path):
    d = tmp_path / "shm"
    d.mkdir()
    seg = d / "fastrtps_dddddddddddddddd"
    _touch(seg, 4096)
    with open(seg, "r+b") as fh:
        mem = mmap.mmap(fh.fileno(), 4096)
    try:
        assert shm.clean_stale(frozenset(), d, min_age_s=0.0) == []
    finally:
        mem.close()
    assert [p.name for p in shm.clean_stale(frozenset(), d, min_age_s=0.0)] == [seg.name]


def test_own_mappings_may_be_ignored_but_not_locks(tmp_path):
    """swarm-up still maps a killed peer's segment; it may clean it, never a locked one."""
    d = tmp_path / "shm"
    d.mkdir()
    dead, live = d / "fastrtps_eeeeeeeeeeeeeeee", d / "fastrtps_ffffffffffffffff"
    for seg in (dead, live):
        _touch(seg, 4096)
        _touch(Path(f"{seg}_el"))
    me = frozenset({os.getpid()})
    with open(dead, "r+b") as fh:
        mem = mmap.mmap(fh.fileno(), 4096)
    lock = open(f"{live}_el", "rb")  # noqa: SIM115 - held across the asserts
    fcntl.flock(lock, fcntl.LOCK_EX)
    try:
        assert shm.stale_files(frozenset(), d, min_age_s=0.0) == []
        removed = shm.clean_stale(frozenset(), d, min_age_s=0.0, ignore_pids=me)
        assert sorted(p.name for p in removed) == [dead.name, f"{dead.name}_el"]
    finally:
        mem.close()
        lock.close()
