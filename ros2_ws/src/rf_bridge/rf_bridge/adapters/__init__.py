"""Channel adapters, one per external system, plus the ROS 2 side."""
