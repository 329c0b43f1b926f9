"""docs/settings.md rendered from shared/settings.py: ``python -m shared.settings_markdown``
prints it (``> docs/settings.md`` writes it); tests/architecture/test_settings_only.py checks
that the committed file is what :func:`markdown` renders."""

from __future__ import annotations

from shared.settings import DEPLOYMENT, Variable, env_text, variables

HEAD = """\
# Settings

Every `ROCO_*` environment variable roco reads, as [shared/settings.py](../shared/settings.py)
declares it; `roco doctor` shows each one's value in this environment. Generated: change the
declarations, then `python -m shared.settings_markdown > docs/settings.md`.

How a value is read: spaces around it are dropped and an empty value counts as unset (the
default). A flag (`1 / 0`) is on with `1`, off with `0`; any other value leaves its default. A
value that does not parse stops what reads it with one line naming the variable and what it
expects. deploy/compose.yaml sets some of them for its containers (its header lists the values
it gives, e.g. `ROCO_REALTIME=1`, `ROCO_RERUN=1`).
"""


def _cell(text: str) -> str:
    """``text`` as a Markdown table cell (``|`` escaped)."""
    return text.replace("|", "\\|")


def _default(value: object) -> str:
    text = env_text(value)
    return f"`{text}`" if text else "unset"


def _row(v: Variable) -> str:
    return f"| `{v.name}` | {_cell(v.kind)} | {_cell(_default(v.default))} | {_cell(v.doc)} |"


def markdown() -> str:
    """The whole of docs/settings.md: the settings roco's Python reads, then the variables
    of the deployment files and the build (shared/settings.py ``DEPLOYMENT``)."""
    lines = [
        HEAD,
        "## Read by roco",
        "",
        "| variable | values | default | what it sets (who reads it) |",
        "|---|---|---|---|",
        *(_row(v) for v in variables().values()),
        "",
        "## Read by the deployment files and the build",
        "",
        "docker compose (deploy/compose.yaml), deploy/entrypoint.sh and setup.py read these; roco's",
        "Python does not. scripts/build_image.sh and scripts/compose_smoke.sh name a few of their own",
        "in their headers.",
        "",
        "| variable | default | what it sets |",
        "|---|---|---|",
        *(f"| `{d.name}` | {_cell(_default(d.default))} | {_cell(d.doc)} |" for d in DEPLOYMENT),
    ]
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    print(markdown(), end="")
