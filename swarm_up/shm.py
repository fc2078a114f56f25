"""Remove the stale Fast DDS shared-memory files that a run leaves in ``/dev/shm``.

Fast DDS (the default RMW of ROS 2 Jazzy) keeps its shared-memory transport in ``/dev/shm``:

- ``fastrtps_<16 hex>``: a participant's segment (mmapped by every process that talks to it),
  with ``fastrtps_<16 hex>_el``, an empty file on which the owner holds an exclusive ``flock``;
- ``fastrtps_port<N>``: a port (a listening queue, shared by the processes of one domain), with
  ``fastrtps_port<N>_el`` (``flock`` of the listener) and the named semaphore
  ``sem.fastrtps_port<N>_mutex``;
- ``fast_datasharing_<guid>...``: data-sharing pools of writers (same scheme, when enabled).

A process that exits cleanly removes its files; one that is killed (SIGKILL, a crash) leaves them.
Fast DDS reclaims some of them later, but not all.  Other programs on the machine (another
swarm-up, a ``ros2`` CLI, another user's nodes) use the same directory at the same time, so the
cleaner removes a file only when all of these hold:

1. its name is a Fast DDS name (the prefixes above);
2. it was not there in the snapshot taken before the run started (it is new, so ours or created
   during our run);
3. its *group* (the segment, its ``_el``/``_sl`` lock files and its ``sem.`` semaphore, which
   share one base name) is not in use by any live process: no member is open (``/proc/*/fd``),
   mmapped (``/proc/*/maps``) or ``flock``-ed (``/proc/locks``) by anyone;
4. it is older than ``min_age_s`` (a file being created right now by someone else is spared).

The process that cleans may exclude its own open files and mappings (``ignore_pids``): a
participant keeps a dead peer's segment mapped until it is destroyed, so swarm-up, whose metrics
node talked to a killed navigator, would otherwise spare that navigator's files until it exits
itself.  Locks are never ignored: a segment whose owner (even this process) holds its ``_el``
lock is live.

The directory is a parameter so that tests can stand a temporary directory in for ``/dev/shm``.
"""

from __future__ import annotations

import os
import re
import time
from pathlib import Path

SHM_DIR = Path("/dev/shm")
FASTDDS_PREFIXES = ("fastrtps_", "fast_datasharing_")
_SEM_PREFIX = "sem."
_GROUP_SUFFIXES = ("_el", "_sl", "_mutex")
_LOCK_RE = re.compile(r"^\d+:\s.*?\s([0-9a-f]+):([0-9a-f]+):(\d+)\s", re.IGNORECASE)


def is_fastdds_name(name: str) -> bool:
    """Whether a file name in ``/dev/shm`` is one Fast DDS creates.

    Args:
        name: the bare file name (no directory).

    Returns:
        True for ``fastrtps_*``, ``sem.fastrtps_*``, ``fast_datasharing_*`` and
        ``sem.fast_datasharing_*``.
    """
    bare = name[len(_SEM_PREFIX):] if name.startswith(_SEM_PREFIX) else name
    return bare.startswith(FASTDDS_PREFIXES)


def group_key(name: str) -> str:
    """The base name shared by a segment and its lock and semaphore files.

    ``fastrtps_port7000``, ``fastrtps_port7000_el`` and ``sem.fastrtps_port7000_mutex`` all give
    ``fastrtps_port7000``.

    Args:
        name: a Fast DDS file name (see :func:`is_fastdds_name`).

    Returns:
        The group's base name.
    """
    key = name[len(_SEM_PREFIX):] if name.startswith(_SEM_PREFIX) else name
    for suffix in _GROUP_SUFFIXES:
        if key.endswith(suffix):
            return key[: -len(suffix)]
    return key


def snapshot(shm_dir: Path | str = SHM_DIR) -> frozenset[str]:
    """The Fast DDS file names present now (take it before the run starts).

    Args:
        shm_dir: the shared-memory directory (``/dev/shm``; a temporary one in tests).

    Returns:
        The set of Fast DDS file names in ``shm_dir`` (empty if it does not exist).
    """
    try:
        return frozenset(n for n in os.listdir(shm_dir) if is_fastdds_name(n))
    except OSError:
        return frozenset()


def _pids() -> list[str]:
    try:
        return [p for p in os.listdir("/proc") if p.isdigit()]
    except OSError:
        return []


def _paths_in_use(shm_dir: Path, ignore_pids: frozenset[int] = frozenset()) -> set[str]:
    """Names in ``shm_dir`` that some live process has open or mmapped (any user we may read),
    bar the processes in ``ignore_pids``."""
    prefix = str(shm_dir) + os.sep
    used: set[str] = set()
    skip = {str(pid) for pid in ignore_pids}
    for pid in _pids():
        if pid in skip:
            continue
        fd_dir = f"/proc/{pid}/fd"
        try:
            fds = os.listdir(fd_dir)
        except OSError:
            fds = []
        for fd in fds:
            try:
                target = os.readlink(f"{fd_dir}/{fd}")
            except OSError:
                continue
            if target.startswith(prefix):
                used.add(target[len(prefix):].removesuffix(" (deleted)"))
        try:
            with open(f"/proc/{pid}/maps", encoding="utf-8", errors="replace") as fh:
                for line in fh:
                    idx = line.find(prefix)
                    if idx >= 0:
                        used.add(line[idx + len(prefix):].rstrip("\n").removesuffix(" (deleted)"))
        except OSError:
            continue
    return used


def _locked_inodes() -> set[tuple[int, int, int]]:
    """``(major, minor, inode)`` of every file that holds a POSIX or flock lock now."""
    locked: set[tuple[int, int, int]] = set()
    try:
        with open("/proc/locks", encoding="utf-8") as fh:
            for line in fh:
                m = _LOCK_RE.match(line)
                if m:
                    locked.add((int(m.group(1), 16), int(m.group(2), 16), int(m.group(3))))
    except OSError:
        pass
    return locked


def in_use_groups(shm_dir: Path | str = SHM_DIR,
                  ignore_pids: frozenset[int] = frozenset()) -> set[str]:
    """Group keys (see :func:`group_key`) of which a live process uses at least one member.

    Args:
        shm_dir: the shared-memory directory.
        ignore_pids: processes whose open files and mappings do not count (their locks do).

    Returns:
        The set of group base names that are open, mmapped or locked by a live process.
    """
    shm_dir = Path(os.path.realpath(shm_dir))
    groups = {group_key(n) for n in _paths_in_use(shm_dir, ignore_pids) if is_fastdds_name(n)}
    locked = _locked_inodes()
    if locked:
        for name in snapshot(shm_dir):
            try:
                st = os.stat(shm_dir / name)
            except OSError:
                continue
            if (os.major(st.st_dev), os.minor(st.st_dev), st.st_ino) in locked:
                groups.add(group_key(name))
    return groups


def stale_files(
    before: frozenset[str] | set[str],
    shm_dir: Path | str = SHM_DIR,
    min_age_s: float = 1.0,
    ignore_pids: frozenset[int] = frozenset(),
) -> list[Path]:
    """The Fast DDS files created since ``before`` that no live process uses.

    Args:
        before: the :func:`snapshot` taken before the run.
        shm_dir: the shared-memory directory.
        min_age_s: spare files whose last status change is younger than this [s].
        ignore_pids: processes whose open files and mappings do not count (their locks do).

    Returns:
        Paths to remove, sorted by name.
    """
    shm_dir = Path(shm_dir)
    new = sorted(snapshot(shm_dir) - set(before))
    if not new:
        return []
    busy = in_use_groups(shm_dir, ignore_pids)
    now = time.time()
    stale = []
    for name in new:
        if group_key(name) in busy:
            continue
        path = shm_dir / name
        try:
            if now - path.lstat().st_ctime < min_age_s:
                continue
        except OSError:
            continue
        stale.append(path)
    return stale


def clean_stale(before: frozenset[str] | set[str], shm_dir: Path | str = SHM_DIR,
                min_age_s: float = 1.0,
                ignore_pids: frozenset[int] = frozenset()) -> list[Path]:
    """Remove the files :func:`stale_files` finds (the arguments are its own); never raises.

    Returns:
        The paths actually removed.
    """
    removed = []
    for path in stale_files(before, shm_dir, min_age_s, ignore_pids):
        try:
            path.unlink()
        except OSError:
            continue
        removed.append(path)
    return removed


def clean_after_run(before: frozenset[str] | set[str], shm_dir: Path | str = SHM_DIR,
                    **where) -> list[Path]:
    """:func:`clean_stale` once a run's processes have all ended, and once more ``min_age_s``
    later if it spared files only for being too young: a participant that was still exiting can
    create or re-create a port file in that last second (a Ctrl-C run left
    ``fastrtps_port7007`` so in CI).  Never raises.

    Args:
        before: the :func:`snapshot` taken before the run.
        shm_dir: the shared-memory directory.
        **where: ``min_age_s``, ``ignore_pids``, as :func:`stale_files` takes them.

    Returns:
        The paths removed.
    """
    removed = clean_stale(before, shm_dir, **where)
    if stale_files(before, shm_dir, **{**where, "min_age_s": 0.0}):
        time.sleep(where.get("min_age_s", 1.0))
        removed += clean_stale(before, shm_dir, **where)
    return removed
