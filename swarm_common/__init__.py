"""Pure, ROS-free pieces shared by the simulator, the navigator and the orchestrator.

Nothing under ``swarm_common`` imports ``rclpy`` or any ``*_msgs`` package (a test checks it).
"""
