"""The Zenoh network: session settings and sessions (docs/architecture.md)."""
