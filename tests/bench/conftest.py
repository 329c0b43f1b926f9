"""The benchmark registers its own content language (L_BENCH) in the process that runs it;
each test here has it registered and gives the registry back as it found it, so that later
tests see roco's six languages only."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from services.bench import messaging
from shared.fipa_codec.languages import base


@pytest.fixture(autouse=True)
def _language_registry_restored() -> Iterator[None]:
    base.load_all()
    languages, by_type = dict(base.LANGUAGES), dict(base._BY_TYPE)
    messaging._register()  # what the bench processes do before they talk
    yield
    base.LANGUAGES.clear()
    base.LANGUAGES.update(languages)
    base._BY_TYPE.clear()
    base._BY_TYPE.update(by_type)
