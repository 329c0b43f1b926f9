"""Control a fleet that keeps running on this machine: ``roco up``, ``down``, ``send``,
``disturb``, ``status`` (the processes themselves: services/fleet/)."""
