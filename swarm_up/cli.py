"""``swarm-up``: bring a whole swarm up with one command, supervise it and measure it.

The contract: docs/reference/contract.md#s2.

The command is split by what each part holds: :mod:`swarm_up.args` (flags and validation),
:mod:`swarm_up.rundir` (run directory and params files), :mod:`swarm_up.children` (the child
processes), :mod:`swarm_up.output` (terminal output) and :mod:`swarm_up.orchestrator` (the run
loop); this module is only the entry point.

Exit codes: 0 success (the run ended by ``--duration`` or Ctrl-C), 2 bad input (also when the
simulator rejects its input, e.g. too many robots for the spawn area), 1 runtime failure (the
simulator crashed, navigators not ready within ``--ready-timeout``, a template missing).
"""

from __future__ import annotations

import sys

from swarm_common.errors import EXIT_RUNTIME, run_cli
from swarm_up import PROG
from swarm_up.args import build_parser, validate_quietly
from swarm_up.orchestrator import run
from swarm_up.output import warn
from swarm_up.rundir import RunError


def main(argv: list[str] | None = None) -> int:
    """Entry point of ``swarm-up``; returns the exit code (0, 1 or 2)."""

    def body() -> int:
        args = build_parser().parse_args(argv)
        cfg, warnings = validate_quietly(args)
        for line in dict.fromkeys(warnings):
            warn(line)
        if cfg.rank == 0:  # the simulator's host: build its message types before it starts
            from swarm_ros.built_interfaces import ensure

            ensure(say=lambda line: print(f"{PROG}: {line}", file=sys.stderr, flush=True),
                   packages=("tf2_msgs", "simulation_interfaces") if cfg.tf
                   else ("simulation_interfaces",))
        try:
            return run(cfg)
        except RunError as exc:
            print(f"{PROG}: error: {exc}", file=sys.stderr, flush=True)
            return EXIT_RUNTIME

    return run_cli(PROG, body)


if __name__ == "__main__":
    sys.exit(main())
