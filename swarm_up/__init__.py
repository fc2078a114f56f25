"""The orchestrator (``swarm-up``): flags, run directory, child processes, supervision, the run
loop, and the group processes it starts."""

PROG = "swarm-up"  # the command's name, first word of its error lines
