"""nav2 simple-commander facade over a swarm navigator's topics."""
