"""Fault injection (``roco fault``, docs/faults.md).

``process``: kill, stop, start, pause, unpause, restart a service of a local fleet (the
launcher's :class:`~services.fleet.launcher.Fleet` or the fleet of ``roco up``), a Python
API that ``roco chaos`` calls too. ``control``: message and network faults of running
agents through their fault layer (``services.runtime.faults``) over Zenoh. ``compose``: the
same faults on a Docker Compose deployment. ``target``: the fleet a fault acts on and the
recorder its events go to. The ``roco fault`` commands: services/cli/fault.py.
"""
