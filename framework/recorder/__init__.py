"""Recording a running graph and replaying recordings into one (docs/recording.md)."""
