"""The six content languages of the Robot Companion (paper §5.4, §5.6) as typed schemas.

| language | channel | what it carries |
|---|---|---|
| ``L_HC``   | C2 | human commands and their outcome |
| ``L_HFSM`` | C1, C3 | ground task networks and hierarchical plans (HFSMs) |
| ``L_SW``   | C1 | supervised-worker states of a_ta |
| ``L_WM``   | C4, C6 | world-model queries, answers and updates (ontology O_RoCo) |
| ``L_EX``   | C5 | low-level executor commands and their results (ontology O_Velma) |
| ``L_SD``   | C5 | sensor data: observations of the scene |

Every language is a tagged union of msgspec Structs encoded as msgpack; decoding is strict.
A system's own languages are declared with :func:`declare`, and an agent's own terms join a
language through :func:`extend` (both from the specification: docs/spec.md).
"""

from shared.fipa_codec.languages.base import (
    LANGUAGES,
    ContentError,
    Language,
    declare,
    decode_content,
    encode_content,
    encode_term,
    extend,
    language_of,
    load_all,
)

__all__ = [
    "LANGUAGES",
    "ContentError",
    "Language",
    "declare",
    "decode_content",
    "encode_content",
    "encode_term",
    "extend",
    "language_of",
    "load_all",
]
