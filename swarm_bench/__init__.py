"""Measuring the swarm: ``swarm-bench`` (:mod:`swarm_bench.bench`), its messaging baseline
(:mod:`swarm_bench.baseline`, whose ROS processes are :mod:`swarm_bench.baseline_nodes`) and
``swarm-experiment`` (:mod:`swarm_bench.experiment`)."""
