"""One robot's navigator: costmap, A*, DWA, holding pattern, recovery, and its ROS 2 shell."""
