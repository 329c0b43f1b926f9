"""Wire encodings of a :class:`Communicate`: msgpack (the wire format) and JSON.

Decoding is strict: unknown performatives, wrong types or truncated bytes raise
:class:`DecodeError`, never anything else. A maximum size (:data:`MAX_COMMUNICATE_BYTES`)
guards against oversized input on decode and keeps an agent from sending it on encode
(:class:`EncodeError`).

The JSON encoding (for tools outside Python)
    One JSON object per communicate, UTF-8, with the FIPA SC00061 §2 parameter names; a
    parameter at its default is left out, and only ``performative`` is required. Fields:

    ==================  ===========================================================================
    ``performative``    string: one of the 22 acts of SC00037, lower case (``"query-ref"``)
    ``sender``          agent identifier, or absent
    ``receiver``        array of agent identifiers (default ``[]``)
    ``reply-to``        array of agent identifiers (default ``[]``)
    ``content``         string: the content **bytes in standard base64** (RFC 4648 §4, with
                        padding); text content is its UTF-8 in base64, roco's msgpack content
                        the msgpack bytes in base64 (default ``""``: no content)
    ``language``        string (``"L_WM"``, ``"fipa-sl"``…), or absent
    ``encoding``        string (roco's languages: ``"msgpack"``), or absent
    ``ontology``        string, or absent
    ``protocol``        string (``"fipa-request"``…), or absent
    ``conversation-id`` string, or absent
    ``reply-with``      string, or absent
    ``in-reply-to``     string, or absent
    ``reply-by``        number: POSIX time in seconds (UTC), finite, or absent
    ``user-params``     object of string values whose keys start with ``X-`` or ``x-``
                        (SC00061 user-defined parameters; default ``{}``)
    ==================  ===========================================================================

    An agent identifier (FIPA SC00023 §4, SC00070 §2.2) is an array
    ``[name, [address, …], [resolver, …], [[X-name, value], …]]``:

    * ``name``: an agent name: a FIPA SC00070 word (no white space or parenthesis, not
      starting with ``# - @ "`` or a digit, not a number or date-time) of at most 255
      characters: ``a_km``, ``da0@host:1099/JADE`` (``shared.fipa_codec.names``);
    * addresses: strings, transport addresses (URLs, each a SC00070 word) in order of preference;
    * resolvers: agent identifiers (the same arrays, recursively, at most 32 deep counting the
      outer one) of the services that can resolve the name;
    * user-defined parameters: ``[name, value]`` pairs of strings, in order; the name includes
      its ``X-`` (or ``x-``) prefix, contains no white space (U+0000–U+0020) and no
      parenthesis, and appears at most once per identifier.

    Trailing items may be left out and count as empty (``["a_km"]``,
    ``["a_km", ["tcp/127.0.0.1:7447"]]``); roco writes all four. Unknown object fields and
    trailing array items are ignored, so that newer writers stay readable. Example::

        {"performative":"inform","sender":["a_co",["tcp/127.0.0.1:7447"],[],[]],
         "receiver":[["a_km",[],[],[]]],"content":"gaR0eXBl","language":"L_WM",
         "reply-by":1795275000.123,"user-params":{"X-priority":"2"}}

    and an agent identifier with a resolver and a user-defined parameter::

        ["da0@jade-platform",["http://robolab:7778/acc"],[["df@jade-platform",[],[],[]]],
         [["X-JADE-agent-classname","examples.PingAgent"]]]

    :func:`json_schema` gives the same as a JSON Schema (2020-12) document, each item of an
    agent identifier described and the name patterns given.
"""

from __future__ import annotations

import math
from typing import Any

import msgspec

from shared.fipa_codec.message import Communicate

MAX_COMMUNICATE_BYTES = 4 * 1024 * 1024
"""Largest communicate (bytes of its encoding) that :func:`encode` writes and :func:`decode`
and :func:`decode_json` accept: 4 MiB. The specification's largest size estimate is 1 MB (a
world-model answer, ``sizes`` in services/spec/robot_companion.toml), the paper's largest
communicate was 852 kB and the messaging benchmark sends 1 MB of content; 4 MiB leaves four
times that. The Zenoh router drops larger publications too (services/runtime/limits.py)."""

_mp_encoder = msgspec.msgpack.Encoder()
_mp_decoder = msgspec.msgpack.Decoder(Communicate)
_json_encoder = msgspec.json.Encoder()
_json_decoder = msgspec.json.Decoder(Communicate)


class DecodeError(ValueError):
    """Bytes that are not a valid communicate. ``reason`` says why, in one line;
    ``oversized`` is True when only the size was wrong (more than the limit)."""

    def __init__(self, reason: str, *, oversized: bool = False) -> None:
        super().__init__(reason)
        self.reason = reason
        self.oversized = oversized


class EncodeError(ValueError):
    """A communicate that may not be sent: its encoding exceeds the size limit."""


def encode(msg: Communicate, max_size: int = MAX_COMMUNICATE_BYTES) -> bytes:
    """Encode ``msg`` as msgpack bytes (the Zenoh payload). ~1 µs for 200 B content.

    Raises EncodeError when the encoding is longer than ``max_size`` bytes (no receiver
    would accept it)."""
    data = _mp_encoder.encode(msg)
    if len(data) > max_size:
        raise too_long(msg, len(data), max_size)
    return data


def too_long(msg: Communicate, size: int, max_size: int = MAX_COMMUNICATE_BYTES) -> EncodeError:
    """The EncodeError of :func:`encode` for ``msg`` encoded in ``size`` bytes."""
    why = f"{msg.performative.value} of {size} bytes exceeds the communicate limit of {max_size}"
    return EncodeError(why)


write = _mp_encoder.encode
""":func:`encode` without its size check (a C function): for the runtime's compiled send path,
which checks the size itself (services/runtime/emission.py)."""
read = _mp_decoder.decode
""":func:`decode` without its size check, raising what msgspec raises (:data:`DECODE_ERRORS`;
:func:`decode_error` says why): for the runtime's compiled receive path, which checks the size
itself and calls no Python for a communicate that decodes (services/runtime/admission.py)."""
DECODE_ERRORS = (msgspec.DecodeError, msgspec.ValidationError, ValueError, RecursionError)
"""What msgspec's decoders raise for bytes that are no communicate (:func:`read`), or no term of
a content language (shared/fipa_codec/languages ``Language.read``); RecursionError: a value
nested beyond the stack (agent identifiers through resolvers, a recursive term)."""


def decode_error(exc: BaseException) -> DecodeError:
    """The DecodeError, saying why in one line, of one of :data:`DECODE_ERRORS` that decoding
    raised (a DecodeError itself as it is)."""
    if isinstance(exc, DecodeError):
        return exc
    if isinstance(exc, RecursionError):
        return DecodeError("agent identifiers nested too deeply")
    return DecodeError(str(exc).splitlines()[0])


def decode(data: bytes | bytearray | memoryview, max_size: int = MAX_COMMUNICATE_BYTES) -> Communicate:
    """Decode msgpack bytes into a :class:`Communicate`.

    Raises DecodeError when the bytes exceed ``max_size``, are not msgpack, or do not match
    the FIPA SC00061 structure (unknown performative, wrong field type, bad agent name…).
    """
    if len(data) > max_size:
        raise DecodeError(f"communicate of {len(data)} bytes exceeds the limit of {max_size}", oversized=True)
    try:
        return _mp_decoder.decode(data)
    except DECODE_ERRORS as exc:
        raise decode_error(exc) from None


def encode_json(msg: Communicate, max_size: int = MAX_COMMUNICATE_BYTES) -> bytes:
    """Encode ``msg`` as the JSON of the module docstring (UTF-8 bytes, one line).

    Raises ValueError when ``reply_by`` is not finite: JSON has no NaN or infinity, and
    writing ``null`` would read back as no ``reply-by`` at all; EncodeError (a ValueError)
    when the JSON is longer than ``max_size`` bytes.
    """
    if msg.reply_by is not None and not math.isfinite(msg.reply_by):
        raise ValueError(f"reply-by {msg.reply_by!r} is not finite and has no JSON form")
    data = _json_encoder.encode(msg)
    if len(data) > max_size:
        raise EncodeError(
            f"{msg.performative.value} of {len(data)} JSON bytes exceeds the communicate limit of {max_size}"
        )
    return data


def decode_json(
    data: bytes | bytearray | memoryview | str, max_size: int = MAX_COMMUNICATE_BYTES
) -> Communicate:
    """Decode the JSON of the module docstring (as written by :func:`encode_json` or any
    other tool). Raises DecodeError when the input exceeds ``max_size`` (bytes or characters),
    is not JSON, or does not match the structure (unknown performative, content not base64,
    user parameter without ``X-``, bad agent name…)."""
    if len(data) > max_size:
        raise DecodeError(f"communicate of {len(data)} bytes exceeds the limit of {max_size}", oversized=True)
    try:
        return _json_decoder.decode(data)
    except DECODE_ERRORS as exc:
        raise decode_error(exc) from None


def json_schema() -> dict[str, Any]:
    """The JSON encoding as a JSON Schema (2020-12) document, for tools outside Python.

    ``$defs/AgentIdentifier`` is the agent identifier array of the module docstring: its
    ``prefixItems`` (name, addresses, resolvers, user-defined parameters) carry a
    ``description`` each, and the name and user parameter name their ``pattern``. What the
    schema cannot say: a user parameter name at most once per identifier, resolvers at most
    32 identifiers deep, and the user parameter keys of ``user-params`` start with ``X-``.
    """
    return msgspec.json.schema(Communicate)
