"""A deployment's credentials and access control: issuing them for a fleet (deploy); its
compose file rendered from the specification (compose), written or checked with its override
(compose_files); a new agent's files (new_agent). The `roco deploy` commands are
services/cli/deploy.py. The credentials' format and their lookup, which the runtime uses, are
in services/security/."""
