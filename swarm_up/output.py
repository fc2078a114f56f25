"""What ``swarm-up`` shows on the terminal while it runs: status lines and the spawn/readiness
progress (the summary table at the end is :func:`swarm_metrics.summary.print_summary`)."""

from __future__ import annotations

import sys

from swarm_up import PROG


def say(text: str) -> None:
    """One status line on stdout, ``swarm-up: <text>``."""
    print(f"{PROG}: {text}", flush=True)


def warn(text: str) -> None:
    """One warning line on stderr, ``swarm-up: warning: <text>``."""
    print(f"{PROG}: warning: {text}", file=sys.stderr, flush=True)


class ProgressView:
    """Spawn and readiness progress: a rich progress bar on a terminal, else plain lines.

    Args:
        total: number of robots.
        tty: draw bars (True) or print a line on every change (False).
    """

    def __init__(self, total: int, tty: bool):
        self.total = total
        self._last = (-1, -1)
        self._progress = None
        if tty:
            from rich.progress import (
                BarColumn,
                MofNCompleteColumn,
                Progress,
                TextColumn,
                TimeElapsedColumn,
            )

            self._progress = Progress(
                TextColumn("{task.description:<18}"), BarColumn(), MofNCompleteColumn(),
                TimeElapsedColumn(), transient=False,
            )
            self._spawn = self._progress.add_task("robots spawned", total=total)
            self._ready = self._progress.add_task("navigators ready", total=total)
            self._progress.start()

    def update(self, spawned: int, ready: int) -> None:
        """Show ``spawned``/``ready`` of ``total`` (spawned is at least ready)."""
        spawned = max(spawned, ready)
        if (spawned, ready) == self._last:
            return
        if self._progress is not None:
            self._progress.update(self._spawn, completed=spawned)
            self._progress.update(self._ready, completed=ready)
        else:
            if spawned != self._last[0]:
                print(f"robots spawned: {spawned}/{self.total}", flush=True)
            if ready != self._last[1]:
                print(f"navigators ready: {ready}/{self.total}", flush=True)
        self._last = (spawned, ready)

    def close(self) -> None:
        """Stop drawing (idempotent)."""
        if self._progress is not None:
            self._progress.stop()
            self._progress = None
