"""A busy machine for tests that must not depend on the machine being quiet.

:class:`BusyLoops` runs CPU-bound loops, each in a session of its own (the kernel's autogroup
scheduling gives the processes of one session one share of the CPU between them, so loops that
shared a session would barely disturb anyone), and optionally a process that keeps the disk
busy. :class:`Pauser` stops (SIGSTOP) one process of a run at a time for a second or two and
continues it (SIGCONT): what a descheduled, swapped-out or VM-paused process does.
"""

from __future__ import annotations

import os
import random
import signal
import subprocess
import sys
import threading
import time

import psutil

_LOOP = "while True: pass"
_DISK = ("import os, time\n"
         "p = os.environ['STRESS_DISK_FILE']\n"
         "while True:\n"
         "    with open(p, 'wb') as f:\n"
         "        for _ in range(64):\n"
         "            f.write(os.urandom(1 << 20)); f.flush(); os.fsync(f.fileno())\n"
         "    os.remove(p)\n")


class BusyLoops:
    """``with BusyLoops(n, disk_file=None):`` — ``n`` busy loops (and a disk writer) for the
    duration of the block; every process is killed at its end."""

    def __init__(self, n: int = 2, disk_file: str | None = None):
        self.n = n
        self.disk_file = disk_file
        self.procs: list[subprocess.Popen] = []

    def __enter__(self) -> BusyLoops:
        for _ in range(self.n):
            self.procs.append(subprocess.Popen([sys.executable, "-c", _LOOP],
                                               start_new_session=True))
        if self.disk_file:
            env = dict(os.environ, STRESS_DISK_FILE=self.disk_file)
            self.procs.append(subprocess.Popen([sys.executable, "-c", _DISK], env=env,
                                               start_new_session=True))
        return self

    def __exit__(self, *exc) -> None:
        for p in self.procs:
            p.kill()
        for p in self.procs:
            p.wait()
        if self.disk_file and os.path.exists(self.disk_file):
            os.remove(self.disk_file)


class Pauser(threading.Thread):
    """Pauses the descendants of process ``root`` whose command line contains one of
    ``patterns``, one at a time, for ``pause_s`` (a range) every ``every_s`` (a range) wall
    seconds, until :meth:`stop`; a paused process is always continued. A process younger than
    ``min_age_s`` is left alone: an rclpy process stopped while it creates its DDS participant
    crashed once (SIGSEGV, a commander, 1 of 4 runs); what is tested is a running process.

    Attributes:
        pauses: (command-line pattern that matched, seconds paused) of every pause.
    """

    def __init__(self, root: int, patterns: tuple[str, ...], pause_s=(1.0, 2.0),
                 every_s=(0.5, 1.5), seed: int = 0, min_age_s: float = 5.0):
        super().__init__(daemon=True)
        self.root = root
        self.patterns = patterns
        self.pause_s = pause_s
        self.every_s = every_s
        self.rng = random.Random(seed)
        self.min_age_s = min_age_s
        self.pauses: list[tuple[str, float]] = []
        self._halt = threading.Event()

    def stop(self) -> None:
        self._halt.set()
        self.join(timeout=10)

    def _targets(self) -> list[tuple[psutil.Process, str]]:
        try:
            kids = psutil.Process(self.root).children(recursive=True)
        except psutil.NoSuchProcess:
            return []
        out = []
        for p in kids:
            try:
                line = " ".join(p.cmdline())
                if time.time() - p.create_time() < self.min_age_s:
                    continue
            except psutil.Error:
                continue
            hit = next((pat for pat in self.patterns if pat in line), None)
            if hit is not None:
                out.append((p, hit))
        return out

    def run(self) -> None:
        while not self._halt.wait(self.rng.uniform(*self.every_s)):
            targets = self._targets()
            if not targets:
                continue
            proc, hit = self.rng.choice(targets)
            pause = self.rng.uniform(*self.pause_s)
            try:
                proc.send_signal(signal.SIGSTOP)
            except psutil.Error:
                continue
            t0 = time.monotonic()
            self._halt.wait(pause)
            try:
                proc.send_signal(signal.SIGCONT)
            except psutil.Error:
                pass
            self.pauses.append((hit, round(time.monotonic() - t0, 2)))
