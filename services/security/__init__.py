"""Credentials of a roco deployment: their files (certs.py: the CA, one identity per agent, the
recorder and the operator) and which folder serves which router endpoint (context.py). The
runtime uses them to authenticate (services/runtime/transport.py); issuing them for a fleet and
the ``roco deploy`` commands are in services/deploy/, the access-control rules derived from the
specification in services/spec_check/acl.py (docs/security.md). Imports nothing of roco."""
