"""Security of a roco deployment: credentials (certs.py), their use by clients and the router
(services/runtime/transport.py) and the ``roco deploy`` commands (cli.py). The access-control
rules themselves are derived from the specification in services/spec/acl.py (docs/security.md)."""
