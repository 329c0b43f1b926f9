"""A system's content languages and an agent's own content terms (docs/spec.md, "Content
languages" and "Content terms of a new agent").

A specification may declare content languages (``[languages.NAME]``: an ontology and the
terms modules that form the vocabulary); :func:`register_languages` registers them.

An agent's entry in the specification may name a ``terms`` module (``terms =
"services.agents.watcher.terms"``): a module of the agent's folder that declares msgspec
Structs, each with its own ``tag``, and lists them in ``TERMS``. :func:`register_terms`
(run by services/spec/model.py ``load``, so by every process that loads the specification:
the agents, the recorder's tools, ``roco spec verify``, replay) imports it and adds each term
to the content language the specification gives it: the language of the performatives whose
``contents`` name the term on the agent's channels, or, when no ``contents`` names it, the one
language of all the agent's channels. The codec (shared/fipa_codec/languages/base.py
``extend``) refuses a term whose name or tag is taken; decoding stays strict.

Every process that loads the specification imports these modules: a terms module imports
msgspec and the codec's shared types only (no agent code, no heavy library).
"""

from __future__ import annotations

import importlib
from functools import cache
from pathlib import Path

import msgspec

from services.spec.model import LanguageSpec, SpecError, SystemSpec, one_line
from shared.fipa_codec.languages import extend, load_all

TERMS = "TERMS"
"""The name a terms module lists its terms under: a tuple of Struct types."""


def register_languages(spec: SystemSpec, path: Path) -> None:
    """Register the content languages ``spec`` declares (``[languages.NAME]``,
    services/spec/model.py ``LanguageSpec``): a name the codec does not have becomes a language
    of its ``ontology`` and ``terms``; a name it has (roco's ``L_WM``, or the same specification
    loaded before) is extended by the terms (a term it has is skipped). Raises SpecError, one
    line naming ``path`` and the language: a terms reference that cannot be imported or names no
    Struct of ``TERMS``, a new language without an ontology or terms, an ontology other than the
    registered language's, or a term the codec refuses (its name or tag taken)."""
    for name, table in spec.languages.items():
        if not name or any(c.isspace() for c in name):
            raise SpecError(f"{path}: language {name!r}: a language's name is one word")
        _register_language(name, table, f"{path}: language {name}")


def _check_table(table: LanguageSpec, ontology: str | None, has_terms: bool, where: str) -> None:
    """A new language (``ontology`` None: the codec has none of the name) has an ontology and
    terms; one the codec has keeps its ``ontology``."""
    if ontology is None and (not table.ontology or not has_terms):
        raise SpecError(f"{where}: a new language needs an ontology and at least one term")
    if ontology is not None and table.ontology and table.ontology != ontology:
        raise SpecError(f"{where}: ontology {table.ontology!r}, but it is {ontology!r}")


def _register_language(name: str, table: LanguageSpec, where: str) -> None:
    """Declare or extend language ``name`` as ``table`` says (:func:`register_languages`)."""
    from shared.fipa_codec.languages.base import declare

    terms = tuple(dict.fromkeys(t for ref in table.terms for t in referenced_terms(ref, where)))
    known = load_all().get(name)
    _check_table(table, known.ontology if known is not None else None, bool(terms), where)
    try:
        if known is None:
            declare(name, table.ontology, *terms)
        else:
            extend(name, *terms)
    except ValueError as exc:
        raise SpecError(f"{where}: {one_line(exc)}") from None


def referenced_terms(ref: str, where: str = "") -> tuple[type[msgspec.Struct], ...]:
    """The Struct types a ``terms`` reference of a language names: ``"module"``, every term its
    ``TERMS`` lists; ``"module:Name"``, the one of them named ``Name``. Raises SpecError
    (prefixed ``where``) as :func:`declared_terms` does, or when ``Name`` is not in ``TERMS``."""
    module, _, name = ref.partition(":")
    terms = declared_terms(module, where)
    if not name:
        return terms
    chosen = tuple(t for t in terms if t.__name__ == name)
    if not chosen:
        prefix = f"{where}: " if where else ""
        raise SpecError(f"{prefix}terms module {module!r} lists no term {name!r} in {TERMS}")
    return chosen


def register_terms(spec: SystemSpec, path: Path) -> None:
    """Import the ``terms`` module of every agent of ``spec`` that names one and add its terms
    to their languages (module docstring). Raises SpecError, one line naming ``path`` and the
    agent: a module that cannot be imported, no ``TERMS`` tuple of Struct types in it, a term
    whose language the channels do not tell, or one the codec refuses (name or tag taken). A
    term that has a language already (a ``[languages.NAME]`` lists it, or another agent names
    the same module) keeps it."""
    for agent in spec.agents:
        if not agent.terms:
            continue
        where = f"{path}: agent {agent.name}"
        for term in declared_terms(agent.terms, where):
            if any(term in lang.types for lang in load_all().values()):
                continue  # declared by a language, or by another agent naming the same module
            languages = term_languages(spec, agent.name, term.__name__)
            if len(languages) != 1:
                why = (
                    "no channel of the agent has a content language"
                    if not languages
                    else (
                        f"its channels allow {', '.join(sorted(languages))}: name it in the `contents` of one"
                    )
                )
                raise SpecError(f"{where}: term {term.__name__} has no one language ({why})")
            try:
                extend(languages.pop(), term)
            except ValueError as exc:
                raise SpecError(f"{where}: {exc}") from None


def declared_terms(module_name: str, where: str = "") -> tuple[type[msgspec.Struct], ...]:
    """The Struct types module ``module_name`` lists in ``TERMS``. Raises SpecError (prefixed
    ``where``) when the module cannot be imported or ``TERMS`` is not a tuple or list of
    msgspec Struct types."""
    prefix = f"{where}: " if where else ""
    try:
        module = importlib.import_module(module_name)
    except Exception as exc:  # any error of the module's code: one line naming it
        raise SpecError(f"{prefix}terms module {module_name!r} cannot be imported: {one_line(exc)}") from None
    terms = getattr(module, TERMS, None)
    if not isinstance(terms, tuple | list) or not all(
        isinstance(t, type) and issubclass(t, msgspec.Struct) for t in terms
    ):
        raise SpecError(f"{prefix}terms module {module_name!r} has no {TERMS} tuple of msgspec Struct types")
    return tuple(terms)


def term_languages(spec: SystemSpec, agent: str, term: str) -> set[str]:
    """The content languages the channels ``agent`` ends give term ``term``: those of the
    performatives whose ``contents`` name it, else every language of those channels."""
    named: set[str] = set()
    every: set[str] = set()
    for ch in spec.channels:
        if agent not in ch.ends:
            continue
        for cp in ch.protocols:
            for performative, language in cp.languages.items():
                languages = {language} if isinstance(language, str) else set(language)
                every |= languages
                if term in cp.content_types(performative):
                    named |= languages
    return named or every


@cache
def load_spec_terms() -> None:
    """Register the content terms of the specification ``ROCO_SPEC`` names (else the Robot
    Companion's), once per process: for a tool that decodes a record without loading the
    specification itself (``roco report``). Raises SpecError as services/spec/model.py
    ``load`` does."""
    from services.spec.model import load, spec_path

    load(spec_path())
