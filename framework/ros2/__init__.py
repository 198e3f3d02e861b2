"""ROS 2 interoperability: handflow messages as ROS 2 types in CDR (docs/ros2.md)."""
