"""Coverage-guided fuzzing of the codec with atheris (optional; ``pip install atheris``).

    python scripts/fuzz_codec.py -atheris_runs=200000          # decode() and content languages
    python scripts/fuzz_codec.py -max_total_time=60 corpus/    # a minute, keep a corpus

Each input is fed to :func:`shared.fipa_codec.decode` (msgpack communicate),
:func:`~shared.fipa_codec.encoding.decode_json` and, by its first byte, to one content
language's decoder. The only exceptions allowed are DecodeError and ContentError; anything
else (or a crash of the interpreter) is a finding, which libFuzzer reports with the input
that caused it. A communicate that decodes must encode back to bytes that decode equal.
"""

from __future__ import annotations

import contextlib
import sys

import atheris

with atheris.instrument_imports():
    from shared.fipa_codec import DecodeError, decode, encode
    from shared.fipa_codec.encoding import decode_json
    from shared.fipa_codec.languages import ContentError, decode_content, load_all

LANGUAGES = sorted(load_all())


def one_input(data: bytes) -> None:
    """libFuzzer's entry point: one input, any bytes."""
    try:
        msg = decode(data)
    except DecodeError:
        pass
    else:
        assert decode(encode(msg, max_size=2**31)) == msg
    with contextlib.suppress(DecodeError):
        decode_json(data)
    if data:
        with contextlib.suppress(ContentError):
            decode_content(LANGUAGES[data[0] % len(LANGUAGES)], data[1:])


def main() -> None:
    atheris.Setup(sys.argv, one_input)
    atheris.Fuzz()


if __name__ == "__main__":
    main()
