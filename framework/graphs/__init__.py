"""Graph files: their schema, validation and loading (docs/pipelines.md)."""
