"""Control a fleet that keeps running on this machine, for ``roco up``, ``down``, ``send``,
``disturb`` and ``status`` (their commands: services/cli/): start it (start.py), stop it and
keep its counters (stop.py), talk to it (talk.py), name its routers (status.py); the processes
themselves: services/fleet/."""
