"""TLS certificates, access control and user/password credentials (docs/security.md)."""
