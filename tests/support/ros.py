"""Helpers for node tests: start/stop processes, an isolated rclpy context, spin until a condition.

The session's ``ROS_DOMAIN_ID`` and ``ROS_AUTOMATIC_DISCOVERY_RANGE`` are set by
``tests/conftest.py``; processes started here inherit them.
"""

from __future__ import annotations

import contextlib
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import rclpy
from rclpy.executors import SingleThreadedExecutor

BIN = Path(sys.executable).parent


def start(cmd: list[str], log: Path) -> subprocess.Popen:
    """Start a console script of ours (``cmd[0]`` from the venv) in its own process group."""
    exe = BIN / cmd[0]
    fh = open(log, "w")  # noqa: SIM115 - closed by stop()
    proc = subprocess.Popen([str(exe), *cmd[1:]], stdout=fh, stderr=subprocess.STDOUT,
                            start_new_session=True, env=os.environ.copy())
    proc._log = fh  # type: ignore[attr-defined]
    return proc


def stop(proc: subprocess.Popen, timeout: float = 5.0) -> int | None:
    """SIGINT, then SIGKILL the process group after ``timeout``; return the exit code."""
    if proc.poll() is None:
        with contextlib.suppress(ProcessLookupError):
            os.killpg(proc.pid, signal.SIGINT)
        try:
            proc.wait(timeout)
        except subprocess.TimeoutExpired:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(2.0)
    proc._log.close()  # type: ignore[attr-defined]
    return proc.returncode


@contextlib.contextmanager
def ros_context():
    """An rclpy context of its own, with a single-threaded executor spun by the caller.

    On exit every node added to the executor is destroyed before the context shuts down: a
    shut-down context whose nodes live on keeps its DDS participant, and its endpoints stay
    discoverable until garbage collection, so a later test would see, say, a ``/swarm/markers``
    subscriber that is long gone (CI stop 33)."""
    ctx = rclpy.Context()
    rclpy.init(context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    try:
        yield ctx, executor
    finally:
        nodes = executor.get_nodes()
        executor.shutdown()
        for node in nodes:
            node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def spin_until(executor, condition, timeout: float, what: str = "condition") -> None:
    """Spin ``executor`` until ``condition()`` holds; AssertionError after ``timeout`` wall s."""
    deadline = time.monotonic() + timeout
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out after {timeout} s waiting for {what}")
        executor.spin_once(timeout_sec=0.05)


def alive(processes) -> list[psutil.Process]:
    """The processes of ``processes`` (psutil) still running; zombies count as gone."""
    out = []
    for p in processes:
        with contextlib.suppress(psutil.Error):
            if p.is_running() and p.status() != psutil.STATUS_ZOMBIE:
                out.append(p)
    return out
