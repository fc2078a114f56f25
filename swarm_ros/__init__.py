"""The ROS side that every node shares: QoS profiles built from :mod:`swarm_common.topics`
(:mod:`swarm_ros.qos`) and the shutdown-tolerant life of a node process
(:mod:`swarm_ros.session`).  It imports only ``rclpy`` and :mod:`swarm_common`, so every package
with a node may use it (:mod:`swarm_common` itself stays free of ROS)."""
