"""Testing plugins: the node harness and message fuzzing (docs/pipelines.md)."""
