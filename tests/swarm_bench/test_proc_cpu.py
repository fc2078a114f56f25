"""TreeCpu: CPU seconds of a process tree between a mark and the last sample."""

from __future__ import annotations

import subprocess
import sys
import time

import pytest

from swarm_bench.proc_cpu import TreeCpu

# A child that burns ~0.4 s of CPU, says so, and waits for its stdin to close; and its parent.
CHILD = ("import sys, time\n"
         "t = time.process_time()\n"
         "while time.process_time() - t < 0.4:\n"
         "    pass\n"
         "print(1, flush=True)\n"
         "sys.stdin.read()\n")
BURN = ("import subprocess, sys\n"
        f"subprocess.run([sys.executable, '-c', {CHILD!r}], stdin=sys.stdin, stdout=sys.stdout)\n")


def test_counts_the_cpu_of_descendants_since_the_mark():
    proc = subprocess.Popen([sys.executable, "-c", BURN], stdin=subprocess.PIPE,
                            stdout=subprocess.PIPE, text=True)
    try:
        cpu = TreeCpu([proc.pid])
        assert cpu.since_mark() is None and not cpu.marked
        cpu.mark()
        assert proc.stdout.readline().strip() == "1"  # the child has burnt its 0.4 s
        time.sleep(0.05)
        cpu.sample()
        assert cpu.since_mark() == pytest.approx(0.4, abs=0.25)
        assert cpu.total() >= cpu.since_mark()
    finally:
        proc.stdin.close()
        proc.wait(10)
        proc.stdout.close()
    # Exited processes keep their last sample; a sample of a dead tree changes nothing.
    before = cpu.total()
    assert cpu.sample() == before
