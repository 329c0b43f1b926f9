"""``roco doctor``'s settings: each variable shared/settings.py declares, its value in this
environment, its default and what it sets; a value that does not parse is a failed item."""

from __future__ import annotations

import os
from collections.abc import Mapping
from dataclasses import dataclass

from services.doctor.model import Check, Use
from shared.settings import Settings, env_text, variables


@dataclass(frozen=True)
class Reading:
    """One setting as read here: ``name`` (``ROCO_…``), ``value`` (as set, stripped; "" when
    unset or empty), ``default`` (as the environment would hold it), ``doc``, and ``error``
    (the one-line reason when the value does not parse, else None)."""

    name: str
    value: str
    default: str
    doc: str
    kind: str
    error: str | None = None


def readings(environ: Mapping[str, str] | None = None) -> list[Reading]:
    """Every setting of ``environ`` (default ``os.environ``), in declaration order."""
    env = os.environ if environ is None else environ
    out = []
    for field, v in variables().items():
        try:
            Settings.from_env(env, only=(field,))
            error = None
        except ValueError as exc:
            error = str(exc)
        value = env.get(v.name, "").strip()
        out.append(Reading(v.name, value, env_text(v.default), v.doc, v.kind, error))
    return out


def checks(environ: Mapping[str, str] | None = None) -> list[Check]:
    """One failed item per setting whose value does not parse (none when all do)."""
    return [
        Check(r.name, Use.SETTINGS, False, r.error, f"unset it, or give {r.kind} (docs/settings.md)")
        for r in readings(environ)
        if r.error is not None
    ]
