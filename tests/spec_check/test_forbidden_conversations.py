"""Conversations FIPA forbids, appended to a real pour's record, make ``roco spec verify`` say no.

Each case appends one conversation to the record of tests/spec_check/fixtures/urgent_mid_pour
(a real pour, every conversation whole, fully conformant as recorded), its communicates cloned
from the record's own (so that channel, language and content are right and only the protocol is
wrong), and requires ``verify`` to flag exactly the communicates that break a rule, naming the
conversation and the rule (FIPA SC00026–SC00036 "Exceptions to IP Flow", SC00037 §3.12
not-understood, SC00061 conversation-id). A legal extra conversation keeps the verdict yes. The
contract nets and the English auction are on no channel of the shipped specification: their
cases run against a copy of it that gives a_co and a_pl those protocols on C3 as well."""

from __future__ import annotations

from pathlib import Path

import pytest
from typer.testing import CliRunner

from services.cli import app
from services.spec.model import DEFAULT_SPEC, load
from services.spec.protocol_defs import protocols_of
from services.spec_check.conformance import ConformanceReport, verify_run
from shared.fipa_codec import Performative
from tests.support import forbidden

FIXTURE = Path(__file__).parent / "fixtures" / "urgent_mid_pour"
"""A real pour's record whose conversations are whole (its README)."""
QUERY = forbidden.QUERY
P = Performative

_ON_C3 = """
  [[channels.protocols]]
  protocol = "{protocol}"
  initiator = "a_co"
  languages = {{ {languages} }}
"""
EXTRA = ("fipa-contract-net", "fipa-iterated-contract-net", "fipa-english-auction")


def _spec_with_more_protocols(dest: Path) -> Path:
    """A copy of the shipped specification whose C3 carries the contract nets and the English
    auction between a_co (initiator) and a_pl, every performative in L_HFSM."""
    from shared.fipa_codec.protocols import PROTOCOLS

    text = DEFAULT_SPEC.read_text()
    marker = 'name = "C3"'
    assert text.count(marker) == 1
    head, _, tail = text.partition(marker)
    body, sep, rest = tail.partition("\n[[channels]]")
    for name in EXTRA:
        machine = PROTOCOLS[name]
        perfs = sorted({perf.value for (_, _, perf) in machine.transitions} - {P.NOT_UNDERSTOOD.value})
        languages = ", ".join(f'{p} = "L_HFSM"' for p in perfs)
        body += _ON_C3.format(protocol=name, languages=languages)
    roles = "".join(
        f"[protocols.{name}]\ninitiator = {_roles(name, 'initiator')}\n"
        f"participant = {_roles(name, 'participant')}\n"
        for name in EXTRA
    )
    path = dest / "spec.toml"
    path.write_text(head + marker + body + sep + rest + "\n" + roles)
    assert load(path).protocols.keys() >= set(EXTRA)
    return path


def _roles(name: str, role: str) -> str:
    from shared.fipa_codec.protocols import PROTOCOLS

    machine = PROTOCOLS[name]
    perfs = sorted({p.value for (_, r, p) in machine.transitions if r == role} - {P.NOT_UNDERSTOOD.value})
    return "[" + ", ".join(f'"{p}"' for p in perfs) + "]"


def _appended(dest: Path, cid: str, protocol: str, steps: forbidden.Steps) -> Path:
    return forbidden.append_conversation(FIXTURE, dest, cid, protocol, steps)


def _verify(run: Path, spec_path: Path = DEFAULT_SPEC) -> ConformanceReport:
    return verify_run(run, load(spec_path), protocols=protocols_of(spec_path))


@pytest.fixture(scope="module")
def more_protocols(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return _spec_with_more_protocols(tmp_path_factory.mktemp("spec"))


def test_the_record_with_nothing_appended_verifies(tmp_path: Path) -> None:
    """The setup is accepted: the fixture copied as the cases copy it conforms fully, and an
    appended conversation is read as one (its communicates counted in it)."""
    assert not _verify(_appended(tmp_path / "run", "nothing", "fipa-query", [])).violations
    report = _verify(_appended(tmp_path / "one", "one", "fipa-query", [(QUERY, P.QUERY_REF)]))
    (one,) = [c for c in report.conversations if c.conversation_id == "one"]
    assert one.messages == 1 and one.agents == ("a_pl", "a_km") and not report.violations


@pytest.mark.parametrize("name", list(forbidden.CASES), ids=list(forbidden.CASES))
def test_a_forbidden_conversation_is_flagged_naming_it_and_the_rule(
    name: str, tmp_path: Path, more_protocols: Path
) -> None:
    protocol, steps, flagged = forbidden.CASES[name]
    cid = "planted-" + name.replace(" ", "-")[:40]
    run = _appended(tmp_path / "run", cid, protocol, steps)
    report = _verify(run, more_protocols if protocol in EXTRA else DEFAULT_SPEC)
    found = {v.position: v for v in report.violations}
    assert set(found) == set(flagged), [(v.position, v.kind, v.text) for v in report.violations]
    for position, words in flagged.items():
        v = found[position]
        assert v.conversation == cid and v.kind == "protocol-state", v
        assert words in v.text, v.text


@pytest.mark.parametrize("name", list(forbidden.LEGAL), ids=list(forbidden.LEGAL))
def test_a_legal_extra_conversation_keeps_full_conformance(
    name: str, tmp_path: Path, more_protocols: Path
) -> None:
    protocol, steps = forbidden.LEGAL[name]
    run = _appended(tmp_path / "run", "legal-extra", protocol, steps)
    report = _verify(run, more_protocols if protocol in EXTRA else DEFAULT_SPEC)
    assert not report.violations, [(v.position, v.text) for v in report.violations]


def test_roco_spec_verify_exits_non_zero_naming_the_conversation_and_the_rule(tmp_path: Path) -> None:
    protocol, steps, _ = forbidden.CASES["a query answered, asked again and answered again"]
    run = _appended(tmp_path / "run", "planted-again", protocol, steps)
    result = CliRunner().invoke(app, ["spec", "verify", str(run)])
    assert result.exit_code != 0, result.output
    assert "full conformance: no" in result.output, result.output
    line = next(
        line for line in result.output.splitlines() if "planted-again" in line and forbidden.OPENS in line
    )
    assert "new conversation-id" in line, line
