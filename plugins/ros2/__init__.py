"""ROS 2 topics into and out of a graph over Zenoh, as rmw_zenoh speaks them (docs/ros2.md)."""
