"""Watching a running graph: the monitor and the Foxglove bridge (docs/monitoring.md)."""
