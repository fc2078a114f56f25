"""The run's metrics: the listener node that hears the swarm (:mod:`swarm_metrics.listener`), the
aggregation into ``metrics.json`` (:mod:`swarm_metrics.aggregate`) and the summary tables
(:mod:`swarm_metrics.summary`)."""
