"""The runtime: launcher, node runner, zygote, discovery and what they share (docs/architecture.md)."""
