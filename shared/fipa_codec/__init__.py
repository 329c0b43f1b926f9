"""The communicate of paper eq. (3) after FIPA SC00061, its encodings and content languages.

Pure data and functions: this package performs no I/O and imports nothing else of roco.
"""

from shared.fipa_codec.acts import Performative
from shared.fipa_codec.aid import AgentIdentifier
from shared.fipa_codec.encoding import DecodeError, EncodeError, decode, encode
from shared.fipa_codec.message import Communicate

__all__ = [
    "AgentIdentifier",
    "Communicate",
    "DecodeError",
    "EncodeError",
    "Performative",
    "decode",
    "encode",
]
