"""The PyBullet simulator: the world, the robots' bodies and sensors, and its ROS 2 shell."""
