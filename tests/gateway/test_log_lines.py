"""One event, one line: what a peer chooses (an agent name, a sentence, a reason) cannot start
a line of the gateway's log or of an agent's (services/runtime/log_format.py)."""

from __future__ import annotations

import io
import json
import logging
import os
import subprocess
import sys
from pathlib import Path

from services.bench.gateway import Inbox, acl, body, envelope, post_now, request
from services.fleet.launcher import free_port
from services.gateway.bridge import open_gateway
from services.runtime.log_format import OneLineFormatter, escape_controls
from services.runtime.memory_transport import MemoryBus
from services.spec.model import default_spec

ROOT = Path(__file__).resolve().parents[2]
BREAKS = "a\nb\rc\x0bd\x0ce\x1cf\x85g\u2028h\u2029i\x1b[31mj\tk"


def test_control_characters_and_line_separators_are_escaped() -> None:
    assert escape_controls(BREAKS) == "a\\nb\\rc\\x0bd\\x0ce\\x1cf\\x85g\\u2028h\\u2029i\\x1b[31mj\\tk"
    assert len(escape_controls(BREAKS).splitlines()) == 1
    record = logging.LogRecord("g", logging.ERROR, __file__, 1, "said %s", (BREAKS,), None)
    try:
        raise ValueError("boom\nTraceback (most recent call last):")
    except ValueError:
        record.exc_info = sys.exc_info()
    assert len(OneLineFormatter().format(record).splitlines()) == 1


def test_the_gateways_log_has_one_line_per_event_whatever_a_peer_sends() -> None:
    stream = io.StringIO()
    handler = logging.StreamHandler(stream)
    handler.setFormatter(OneLineFormatter())
    logger = logging.getLogger("gateway")
    logger.addHandler(handler)
    records: list[logging.LogRecord] = []

    class Counter(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    counter = Counter()
    logger.addHandler(counter)
    port = free_port()
    url = f"http://127.0.0.1:{port}/acc"
    gateway, server = open_gateway(MemoryBus().transport(), default_spec(), "127.0.0.1", port, url)
    inbox = Inbox()
    try:
        name = "da0\u2028INFO\x85forged@host:1099/JADE"  # a SC00070 word: no character below U+0021
        content = json.dumps(
            {"type": "sentence", "text": "x\n2026-01-01 gateway INFO forged"}, ensure_ascii=False
        )
        payload = acl(name, "a_co", content, "c\u2028x", inbox.address).encode()
        data = request(url, body(envelope("a_co", "da0@host", len(payload)), payload))
        assert post_now(("127.0.0.1", port), data) == 200
        inbox.next()  # the refuse: the gateway logged the refusal before posting it
        bad = request(
            url, b"\n".join([b"--x", b"\x1b[2J\r\nforged line"]), content_type="multipart/mixed; boundary=x"
        )
        assert post_now(("127.0.0.1", port), bad) == 406
    finally:
        inbox.close()
        server.stop()
        gateway.stop()
        logger.removeHandler(handler)
        logger.removeHandler(counter)
    text = stream.getvalue()
    assert len(records) >= 2 and text.count("\n") == len(records)
    assert len(text.splitlines()) == len(records)  # str.splitlines splits at U+2028, U+0085 too
    assert "\\u2028" in text and "\\x85" in text


def test_an_agents_log_has_one_line_per_event(tmp_path: Path) -> None:
    code = (
        "import logging; from services.runtime.main import setup_logging; setup_logging('a_hi'); "
        f"logging.getLogger('a_hi').info('sentence from %s: %s', 'da0@h', {BREAKS!r})"
    )
    env = {**os.environ, "ROCO_RUN_DIR": str(tmp_path), "PYTHONPATH": str(ROOT)}
    subprocess.run([sys.executable, "-c", code], env=env, check=True, timeout=60)
    text = (tmp_path / "logs" / "a_hi.log").read_text()
    assert len(text.splitlines()) == 1 and text.endswith("\\tk\n")
