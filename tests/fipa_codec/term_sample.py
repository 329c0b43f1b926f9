"""A sample of a content term built from its own declaration (msgspec.inspect): its required
fields get the simplest value their type and constraints allow, the others their defaults.
For a term with no hand-written sample (fipa_strategies.SAMPLE_TERMS): an agent's own term
(services/spec/terms.py) is tested without anyone writing one."""

from __future__ import annotations

from typing import Any

import msgspec
import msgspec.inspect as mi


class NoSample(TypeError):
    """A field type the builder has no value for."""


def build_sample(kind: type[msgspec.Struct]) -> msgspec.Struct:
    """An instance of Struct type ``kind``; raises NoSample for a field type with no simple
    value (e.g. a datetime)."""
    value = _value(mi.type_info(kind))
    assert isinstance(value, msgspec.Struct)
    return value


def _value(t: mi.Type) -> Any:
    if isinstance(t, mi.Metadata) and isinstance(t.type, mi.RawType) and "language" in (t.extra or {}):
        return _term_of(str((t.extra or {})["language"]))  # a term of that language, taken as raw bytes
    if isinstance(t, mi.Metadata):
        return _value(t.type)
    if isinstance(t, mi.StructType):
        return t.cls(**{f.name: _value(f.type) for f in t.fields if f.required})
    if isinstance(t, mi.StrType):
        return "x" * max(1, t.min_length or 0)
    if isinstance(t, mi.BoolType):
        return False
    if isinstance(t, mi.IntType | mi.FloatType):
        low = t.ge if t.ge is not None else (t.gt + 1 if t.gt is not None else 0)
        return float(low) if isinstance(t, mi.FloatType) else int(low)
    if isinstance(t, mi.NoneType | mi.AnyType):
        return None
    if isinstance(t, mi.BytesType):
        return b"x" * (t.min_length or 0)
    if isinstance(t, mi.TupleType):
        return tuple(_value(x) for x in t.item_types)
    if isinstance(t, mi.VarTupleType | mi.ListType | mi.SetType | mi.FrozenSetType):
        items = [_value(t.item_type)] * (t.min_length or 0)
        return {mi.VarTupleType: tuple, mi.ListType: list, mi.SetType: set, mi.FrozenSetType: frozenset}[
            type(t)
        ](items)
    if isinstance(t, mi.DictType):
        return {}
    if isinstance(t, mi.EnumType):
        return next(iter(t.cls))
    if isinstance(t, mi.LiteralType):
        return t.values[0]
    if isinstance(t, mi.UnionType):
        return _value(next((x for x in t.types if not isinstance(x, mi.NoneType)), t.types[0]))
    raise NoSample(f"no simple value of {type(t).__name__}")


def _term_of(language: str) -> msgspec.Raw:
    """The encoded sample of the first term of ``language`` the builder has a value for."""
    from shared.fipa_codec.languages import LANGUAGES, encode_term

    for kind in LANGUAGES[language].types:
        try:
            return msgspec.Raw(encode_term(build_sample(kind)))
        except NoSample:
            continue
    raise NoSample(f"no term of {language} has a simple value")
