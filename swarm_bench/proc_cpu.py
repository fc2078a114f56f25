"""CPU seconds of a process tree between two moments, for ``swarm-bench`` (psutil, no ROS).

:class:`TreeCpu` samples a set of root processes and all their descendants and keeps, per
process, the largest CPU time (user + system) seen: a process that exits between two samples
keeps what it had used at its last sample (its last fraction of a second is lost, not its
whole history).  ``mark()`` … ``total()`` then gives the CPU seconds spent in between.
"""

from __future__ import annotations

from collections.abc import Iterable

import psutil


class TreeCpu:
    """CPU time of process trees, sampled.

    Args:
        roots: the PIDs whose trees are sampled (more may be added with :meth:`add_root`).
    """

    def __init__(self, roots: Iterable[int] = ()):
        self.roots = list(roots)
        self._procs: dict[int, psutil.Process] = {}
        self._cpu_s: dict[int, float] = {}  # [s] per PID, the largest seen
        self._mark_s: float | None = None
        self._mark_by_pid: dict[int, float] = {}
        self.cmdlines: dict[int, str] = {}
        """Each sampled PID's command line, read when it was first seen."""

    def add_root(self, pid: int) -> None:
        """Sample the tree of ``pid`` too."""
        self.roots.append(pid)

    def sample(self) -> float:
        """Read the CPU times of every live process of the trees now.

        Returns:
            The total CPU seconds seen so far, all processes (dead ones at their last sample).
        """
        seen: list[psutil.Process] = []
        for pid in self.roots:
            try:
                root = self._procs.get(pid) or psutil.Process(pid)
                seen.append(root)
                seen.extend(root.children(recursive=True))
            except psutil.Error:
                continue
        for proc in seen:
            proc = self._procs.setdefault(proc.pid, proc)
            try:
                cpu = proc.cpu_times()
            except psutil.Error:
                continue
            used = cpu.user + cpu.system
            self._cpu_s[proc.pid] = max(self._cpu_s.get(proc.pid, 0.0), used)
            if proc.pid not in self.cmdlines:
                try:
                    self.cmdlines[proc.pid] = " ".join(proc.cmdline())
                except psutil.Error:
                    self.cmdlines[proc.pid] = ""
        return self.total()

    def total(self) -> float:
        """CPU seconds seen so far, all processes [s]."""
        return sum(self._cpu_s.values())

    def mark(self) -> None:
        """Sample now and remember the total: :meth:`since_mark` counts from here."""
        self._mark_s = self.sample()
        self._mark_by_pid = dict(self._cpu_s)

    @property
    def marked(self) -> bool:
        """Whether :meth:`mark` was called."""
        return self._mark_s is not None

    def since_mark(self) -> float | None:
        """CPU seconds between :meth:`mark` and the last :meth:`sample`; None without a mark."""
        if self._mark_s is None:
            return None
        return self.total() - self._mark_s

    def by_pid_since_mark(self) -> dict[int, float]:
        """CPU seconds of each PID between :meth:`mark` and the last :meth:`sample` (a process
        started after the mark counts from 0); empty without a mark."""
        if self._mark_s is None:
            return {}
        return {pid: used - self._mark_by_pid.get(pid, 0.0) for pid, used in self._cpu_s.items()}
