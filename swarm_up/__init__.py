"""The orchestrator (``swarm-up``), metrics and the benchmark (``swarm-bench``)."""
