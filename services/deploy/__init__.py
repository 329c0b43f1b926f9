"""A deployment's credentials and access control: issuing them for a fleet (deploy); its
compose file rendered from the specification (compose); and the `roco deploy` commands (cli).
The credentials' format and their lookup, which the runtime uses, are in services/security/."""
