"""The codec's registry of content languages put back as it was (shared/fipa_codec/languages/
base.py): for a test that adds terms of its own to a language (``extend``, or a specification
whose agent names a ``terms`` module), so that its terms leave with it."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import pytest

from shared.fipa_codec.languages import base, load_all


@contextmanager
def languages_restored() -> Iterator[None]:
    """The registry after the block is the registry before it."""
    load_all()
    languages, by_type = dict(base.LANGUAGES), dict(base._BY_TYPE)
    try:
        yield
    finally:
        base.LANGUAGES.clear()
        base.LANGUAGES.update(languages)
        base._BY_TYPE.clear()
        base._BY_TYPE.update(by_type)


@pytest.fixture(autouse=True)
def languages_leave_with_each_test() -> Iterator[None]:
    """Autouse in a test module that imports it: what a test's loading of a specification
    registers in this process (another system's languages, an agent's terms) leaves with the test,
    so that no later test in the same worker sees it."""
    with languages_restored():
        yield
