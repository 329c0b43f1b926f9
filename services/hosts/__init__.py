"""Two hosts on one machine: network namespaces, the link between them, the fleet across them
(docs/deploy.md)."""
