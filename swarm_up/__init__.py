"""The orchestrator (``swarm-up``), its group processes and metrics."""

PROG = "swarm-up"  # the command's name, first word of its error lines
