"""Starting and stopping a fleet of processes (router, recorder, one per agent) on this
machine: the launcher, above the runtime (it issues credentials and the access control)."""
