"""Run the Robot Companion, talk to a running fleet, and read its run folders.

Examples:

    roco doctor                              what this machine offers roco
    roco run "pour the jar into the bowl"    the whole system, to the task's end
    roco scenario urgent_mid_pour            several commands, each one checked
    roco up; roco send "stop"; roco down     a fleet that keeps running
    roco view runs/<timestamp>               a run's Rerun recording

Each command's own --help gives its details. Every failure prints one line starting
with "roco:" and exits non-zero. Shell completion: roco --install-completion.
"""

from __future__ import annotations

import sys

import typer

from services.bench.cli import bench_app
from services.cli_common import MARKUP
from services.control.cli import control_app
from services.control.status_cli import status_app
from services.control.talk_cli import talk_app
from services.deploy.cli import deploy_app, new_agent_app
from services.doctor.cli import doctor_app
from services.fault.cli import fault_app
from services.gateway.cli import gateway_app
from services.hosts.cli import hosts_app
from services.replay.cli import replay_app
from services.ros2.cli import export_app
from services.ros2.live_cli import ros2_app
from services.scenario.chaos_cli import chaos_app
from services.scenario.cli import scenario_app
from services.sniff.cli import sniff_app
from services.spec_check.cli import spec_app
from services.spec_check.report_cli import report_app
from services.viewer.cli import view_app

app = typer.Typer(no_args_is_help=True, help=__doc__, rich_markup_mode=MARKUP)
# the commands, in the order `roco --help` lists them: each tool's app adds its own
for commands in (
    scenario_app,  # run, scenario
    chaos_app,  # chaos
    control_app,  # up, down
    talk_app,  # send, disturb
    view_app,  # view
    sniff_app,  # sniff
    gateway_app,  # gateway
    ros2_app,  # ros2
    status_app,  # status
    replay_app,  # replay
    doctor_app,  # doctor
    report_app,  # report
    export_app,  # export
):
    app.add_typer(commands)
spec_app.add_typer(new_agent_app)  # spec new-agent: in deploy, as it writes the compose files too
for name, group in (
    ("fault", fault_app),
    ("deploy", deploy_app),
    ("hosts", hosts_app),
    ("bench", bench_app),
    ("spec", spec_app),
):
    app.add_typer(group, name=name)


def main() -> None:
    """The ``roco`` console script: exit status 130 when interrupted (Ctrl-C)."""
    try:
        app()
    except KeyboardInterrupt:
        sys.exit(130)


if __name__ == "__main__":
    main()
