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

from services.cli.bench import bench_app
from services.cli.chaos import chaos_app
from services.cli.common import MARKUP
from services.cli.deploy import deploy_app
from services.cli.disturb import disturb_app
from services.cli.doctor import doctor_app
from services.cli.down import down_app
from services.cli.export import export_app
from services.cli.fault import fault_app
from services.cli.gateway import gateway_app
from services.cli.hosts import hosts_app
from services.cli.replay import replay_app
from services.cli.report import report_app
from services.cli.ros2 import ros2_app
from services.cli.run import run_app
from services.cli.scenario import scenario_app
from services.cli.send import send_app
from services.cli.sniff import sniff_app
from services.cli.spec import spec_app
from services.cli.status import status_app
from services.cli.up import up_app
from services.cli.view import view_app

app = typer.Typer(no_args_is_help=True, help=__doc__, rich_markup_mode=MARKUP)
# the commands, in the order `roco --help` lists them: each is services/cli/<its name>.py
for commands in (
    run_app,
    scenario_app,
    chaos_app,
    up_app,
    down_app,
    send_app,
    disturb_app,
    view_app,
    sniff_app,
    gateway_app,
    ros2_app,
    status_app,
    replay_app,
    doctor_app,
    report_app,
    export_app,
):
    app.add_typer(commands)
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
