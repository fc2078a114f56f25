"""The central coordinator of ``swarm-up --coordination centralized``: ``core`` (pure: task
assignment and first-come-first-served reservations) and ``node`` (``swarm-coordinator``)."""
