"""Registry of content languages and strict content encoding/decoding."""

from __future__ import annotations

import importlib
import pkgutil
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgspec
import msgspec.inspect

from shared.fipa_codec.encoding import DECODE_ERRORS


class ContentError(ValueError):
    """Content that does not conform to its language (wrong bytes, wrong type, unknown language)."""


@dataclass(frozen=True)
class Language:
    """A content language: a ``name`` (the ACL ``language`` parameter), the ``ontology`` its
    terms come from, and the Struct types that form its vocabulary (a tagged union).
    ``read`` decodes a term as :meth:`decode` does, raising what msgspec raises instead
    (:data:`DECODE_ERRORS`; :meth:`error` says why): a C function, for the runtime's compiled
    receive path (services/runtime/intake.py)."""

    name: str
    ontology: str
    types: tuple[type[msgspec.Struct], ...]
    read: Callable[[bytes], msgspec.Struct] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        union: Any = self.types[0] if len(self.types) == 1 else _union(self.types)
        object.__setattr__(self, "read", msgspec.msgpack.Decoder(union).decode)

    def decode(self, data: bytes) -> msgspec.Struct:
        """Decode ``data``; raises ContentError when it is not a term of this language
        (including a term nested deeper than the interpreter's recursion limit allows)."""
        try:
            return self.read(data)
        except DECODE_ERRORS as exc:
            raise self.error(exc) from None

    def error(self, exc: BaseException) -> ContentError:
        """The ContentError, saying why in one line, of one of :data:`DECODE_ERRORS` that
        decoding a term raised."""
        if isinstance(exc, RecursionError):  # a recursive term (e.g. L_HFSM PlanNode) nested beyond the stack
            return ContentError(f"{self.name}: content nested too deeply")
        return ContentError(f"{self.name}: {str(exc).splitlines()[0]}")


def _union(types: tuple[type[msgspec.Struct], ...]) -> Any:
    import functools
    import operator

    return functools.reduce(operator.or_, types)


_encoder = msgspec.msgpack.Encoder()
LANGUAGES: dict[str, Language] = {}
_BY_TYPE: dict[type, Language] = {}


def register(language: Language) -> Language:
    """Add ``language`` to the registry; raises ValueError if a name or type is taken."""
    if language.name in LANGUAGES:
        raise ValueError(f"language {language.name} registered twice")
    for t in language.types:
        if t in _BY_TYPE:
            raise ValueError(f"{t.__name__} already belongs to {_BY_TYPE[t].name}")
    for t in language.types:  # only once all are known to be free: no half registration
        _BY_TYPE[t] = language
    LANGUAGES[language.name] = language
    return language


def extend(language: str, *terms: type[msgspec.Struct]) -> Language:
    """Add ``terms`` (msgspec Struct types, each with its own ``tag``) to the vocabulary of the
    registered content language ``language`` and return the language as extended: how an agent
    outside this package declares content terms of its own (services/spec/terms.py loads the
    ``terms`` module an agent's entry in the specification names; docs/spec.md, "Content terms
    of a new agent"). Decoding stays strict: the language decodes its own terms and these,
    nothing else. A term already in ``language`` is skipped (registering twice is harmless).

    Raises ValueError, nothing registered, when ``language`` is not registered, a term is not a
    Struct type or has no tag, belongs to another language, has the name of a registered term
    (the specification names terms by name), or has the tag of a term of ``language``."""
    _load_all()
    known = LANGUAGES.get(language)
    if known is None:
        raise ValueError(
            f"no content language {language!r} to extend (known: {', '.join(sorted(LANGUAGES))})"
        )
    new = tuple(dict.fromkeys(t for t in terms if t not in known.types))
    if not new:
        return known
    _check_new_terms(language, known.types, new)
    try:
        extended = Language(known.name, known.ontology, known.types + new)
    except TypeError as exc:  # msgspec refuses the union (e.g. another tag field)
        raise ValueError(
            f"{language}: {', '.join(t.__name__ for t in new)} cannot join it: {str(exc).split(' - ')[0]}"
        ) from None
    LANGUAGES[language] = extended
    for t in extended.types:
        _BY_TYPE[t] = extended
    return extended


def declare(language: str, ontology: str, *terms: type[msgspec.Struct]) -> Language:
    """Register a new content language ``language`` of ``ontology`` whose vocabulary is
    ``terms`` (msgspec Struct types, each with its own ``tag``): how a system declares its own
    languages (services/spec/terms.py reads them from the specification's ``[languages.NAME]``).

    Raises ValueError, nothing registered, when ``language`` is registered already, ``terms``
    is empty, or a term is refused as :func:`extend` refuses it."""
    _load_all()
    if language in LANGUAGES:
        raise ValueError(f"language {language} registered twice")
    new = tuple(dict.fromkeys(terms))
    if not new:
        raise ValueError(f"{language}: a language has at least one term")
    _check_new_terms(language, (), new)
    try:
        return register(Language(language, ontology, new))
    except TypeError as exc:  # msgspec refuses the union (e.g. another tag field)
        raise ValueError(f"{language}: its terms cannot form one union: {str(exc).split(' - ')[0]}") from None


def _check_new_terms(
    language: str, known: tuple[type[msgspec.Struct], ...], new: tuple[type[msgspec.Struct], ...]
) -> None:
    """Raise ValueError unless each of ``new`` may join ``language`` whose vocabulary is
    ``known``: a tagged Struct type of no language, its name and tag free."""
    names = {t.__name__: lang.name for t, lang in _BY_TYPE.items()}
    tags = {_tag(t): t.__name__ for t in known if _tagged(t)}
    for t in new:
        if not (isinstance(t, type) and issubclass(t, msgspec.Struct)):
            raise ValueError(f"{language}: a content term is a msgspec Struct type, not {t!r}")
        if not _tagged(t):
            raise ValueError(f"{language}: term {t.__name__} has no tag (declare it with tag=...)")
        if t in _BY_TYPE:
            raise ValueError(f"{language}: term {t.__name__} already belongs to {_BY_TYPE[t].name}")
        if t.__name__ in names:
            raise ValueError(f"{language}: a term named {t.__name__} is already in {names[t.__name__]}")
        if _tag(t) in tags:
            raise ValueError(f"{language}: term {t.__name__} has tag {_tag(t)!r}, the tag of {tags[_tag(t)]}")
        names[t.__name__] = language
        tags[_tag(t)] = t.__name__


def _tagged(t: type[msgspec.Struct]) -> bool:
    info = msgspec.inspect.type_info(t)
    return isinstance(info, msgspec.inspect.StructType) and info.tag is not None


def _tag(t: type[msgspec.Struct]) -> object:
    info = msgspec.inspect.type_info(t)
    assert isinstance(info, msgspec.inspect.StructType)
    return info.tag


def language_of(term: msgspec.Struct) -> Language:
    """The language whose vocabulary contains ``term``'s type; raises ContentError if none."""
    _load_all()
    try:
        return _BY_TYPE[type(term)]
    except KeyError:
        raise ContentError(f"{type(term).__name__} belongs to no content language") from None


def encode_content(term: msgspec.Struct) -> tuple[str, bytes]:
    """Encode a language term: returns (language name, msgpack bytes)."""
    return language_of(term).name, encode_term(term)


encode_term = _encoder.encode
"""The msgpack bytes of a language term, its language not looked up (a C function: the runtime
calls it for every communicate it sends, once :func:`language_of` found the term's type a
language)."""


def decode_content(language: str | None, data: bytes) -> msgspec.Struct:
    """Decode ``data`` as a term of ``language``; raises ContentError for an unknown language
    or content that does not conform to it."""
    _load_all()
    if language is None or language not in LANGUAGES:
        raise ContentError(f"unknown content language {language!r}")
    return LANGUAGES[language].decode(data)


def load_all() -> dict[str, Language]:
    """Register every content language of roco (each module registers itself on import) and
    return the registry ``LANGUAGES``."""
    _load_all()
    return LANGUAGES


_loaded = False
"""True once every language module is imported (a flag: the import statement itself costs
≈ 3 µs per call, paid twice per received communicate otherwise)."""


LANGUAGE_MODULE_PREFIX = "l_"
"""A module of this package whose name starts so defines one content language and registers
it on import: the modules are the one list of roco's content languages (the specification names
them per channel, and ``roco spec check`` finds a name no module registers)."""


def _load_all() -> None:
    # Importing the language modules registers them.
    global _loaded
    if _loaded:
        return
    package = __name__.rpartition(".")[0]
    for info in pkgutil.iter_modules([str(Path(__file__).parent)]):
        if info.name.startswith(LANGUAGE_MODULE_PREFIX):
            importlib.import_module(f"{package}.{info.name}")
    _loaded = True
