"""Rerun views of a run: one recording per run shared by the processes that log
(recording.py), traffic (traffic.py), robot and scene (robot.py), the layout
(blueprint.py) and opening a viewer (view.py). Logging is on with ``ROCO_RERUN=1``
(shared/settings.py)."""
