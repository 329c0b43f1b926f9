"""A new agent's own content terms, declared in its folder and named by its entry in the
specification (services/spec/terms.py), join the language its channel gives them without an
edit of shared/fipa_codec; decoding stays strict; a taken name or tag is refused."""

from __future__ import annotations

import itertools
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path

import msgspec
import pytest

from services.spec.model import DEFAULT_SPEC, SpecError, load
from services.spec.terms import term_languages
from shared.fipa_codec.languages import (
    ContentError,
    decode_content,
    encode_content,
    language_of,
    load_all,
)
from shared.fipa_codec.languages.l_wm import ObjectQuery
from tests.support.codec_registry import languages_restored

_ids = itertools.count()

MOVED = """
import msgspec


class Moved(msgspec.Struct, frozen=True, tag="moved", kw_only=True):
    name: str
    distance_m: float = 0.0


TERMS = (Moved,)
"""

AGENT = """
[[agents]]
name = "a_kw"
implementation = "services.agents.knowledge.agent:KnowledgeManager"
group = "kw"
terms = "{module}"

[[channels]]
name = "C9"
ends = ["a_kw", "a_km"]
transmits = "the kitchen watcher's reports of moved things"
  [[channels.protocols]]
  protocol = "fipa-request"
  initiator = "a_kw"
  languages = {{ request = "L_WM", agree = "L_WM", inform = "L_WM", failure = "L_WM", refuse = "L_WM" }}
  contents = {{ request = [{named}] }}
"""


@pytest.fixture(autouse=True)
def registry_restored() -> Iterator[None]:
    """The codec's registry as it was before the test (a test's languages leave with it)."""
    with languages_restored():
        yield


Spec = Callable[..., Path]


@pytest.fixture
def agent_spec(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Spec:
    """Writes an agent folder (a package with ``terms.py``) under ``tmp_path`` and the Robot
    Companion's specification with agent a_kw naming it; returns the specification's path."""
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(terms: str = MOVED, named: str = '"Moved"', module: str | None = None) -> Path:
        package = f"kw_agent_{next(_ids)}"
        (tmp_path / package).mkdir()
        (tmp_path / package / "__init__.py").write_text("")
        (tmp_path / package / "terms.py").write_text(textwrap.dedent(terms))
        path = tmp_path / f"{package}.toml"
        extra = AGENT.format(module=module or f"{package}.terms", named=named)
        path.write_text(DEFAULT_SPEC.read_text() + extra)
        return path

    return write


def _moved(spec: Path) -> type[msgspec.Struct]:
    agent = next(a for a in load(spec).agents if a.name == "a_kw")
    return next(t for t in load_all()["L_WM"].types if t.__module__ == agent.terms)


def test_a_term_of_the_agents_folder_round_trips_in_its_channels_language(agent_spec: Spec) -> None:
    moved = _moved(agent_spec())
    term = moved(name="jar", distance_m=0.12)
    language, data = encode_content(term)
    assert language == "L_WM" and language_of(term).name == "L_WM"
    assert decode_content("L_WM", data) == term
    assert decode_content(*encode_content(ObjectQuery("jar"))) == ObjectQuery("jar")  # its own terms too


def test_the_language_is_the_one_of_the_performatives_naming_the_term(agent_spec: Spec) -> None:
    spec = load(agent_spec())
    assert term_languages(spec, "a_kw", "Moved") == {"L_WM"}
    assert term_languages(spec, "a_km", "Moved") == {"L_WM"}


def test_decoding_stays_strict(agent_spec: Spec) -> None:
    moved_bytes = msgspec.msgpack.encode({"type": "moved", "name": "jar"})
    with pytest.raises(ContentError):  # not registered before the specification is loaded
        decode_content("L_WM", moved_bytes)
    _moved(agent_spec())
    assert decode_content("L_WM", moved_bytes) is not None
    for data in (msgspec.msgpack.encode({"type": "nope"}), msgspec.msgpack.encode({"type": "moved"})):
        with pytest.raises(ContentError, match="L_WM"):
            decode_content("L_WM", data)
    with pytest.raises(ContentError):  # in L_WM only
        decode_content("L_HC", moved_bytes)


def test_loading_twice_registers_once(agent_spec: Spec) -> None:
    path = agent_spec()
    moved = _moved(path)
    before = load_all()["L_WM"].types
    load(path)
    assert load_all()["L_WM"].types == before and before.count(moved) == 1


TAKEN_TAG = """
import msgspec


class Lookup(msgspec.Struct, tag="object"):
    name: str


TERMS = (Lookup,)
"""

TAKEN_NAME = """
import msgspec


class Answer(msgspec.Struct, tag="kw_answer"):
    text: str


TERMS = (Answer,)
"""

UNTAGGED = """
import msgspec


class Plain(msgspec.Struct):
    text: str


TERMS = (Plain,)
"""


@pytest.mark.parametrize(
    ("terms", "named", "why"),
    [
        (TAKEN_TAG, '"Lookup"', "term Lookup has tag 'object', the tag of ObjectQuery"),
        (TAKEN_NAME, '"Answer"', "a term named Answer is already in L_WM"),
        (UNTAGGED, '"Plain"', "term Plain has no tag"),
        ("import msgspec\n", '"Moved"', "has no TERMS tuple"),
        ("TERMS = (int,)\n", '"Moved"', "has no TERMS tuple"),
        ("raise RuntimeError('broken')\n", '"Moved"', "cannot be imported: broken"),
    ],
    ids=["taken tag", "taken name", "no tag", "no TERMS", "TERMS not Structs", "module raises"],
)
def test_a_term_that_cannot_join_is_refused_with_the_agent_named(
    agent_spec: Spec, terms: str, named: str, why: str
) -> None:
    before = dict(load_all())
    with pytest.raises(SpecError, match=f"agent a_kw: .*{why}") as caught:
        load(agent_spec(terms, named))
    assert "\n" not in str(caught.value)
    assert load_all() == before  # nothing half-registered


def test_a_missing_terms_module_is_refused(agent_spec: Spec) -> None:
    with pytest.raises(SpecError, match=r"terms module 'no_such_pkg\.terms' cannot be imported"):
        load(agent_spec(module="no_such_pkg.terms"))


def test_a_term_no_one_language_fits_is_refused(agent_spec: Spec) -> None:
    # not named in any contents: a_kw's channels give L_WM only, so it is L_WM
    assert _moved(agent_spec(named='"Other"')).__name__ == "Moved"
    path = agent_spec(named='"Other"')
    text = path.read_text().replace('failure = "L_WM", refuse', 'failure = "L_HC", refuse')
    path.write_text(text)
    with pytest.raises(SpecError, match=r"term Moved has no one language \(its channels allow L_HC, L_WM"):
        load(path)


def test_the_report_decodes_a_term_of_the_specification_roco_spec_names(
    agent_spec: Spec, monkeypatch: pytest.MonkeyPatch
) -> None:
    from services.recorder.record import TrafficRecord
    from services.report.load import _decode_all
    from services.spec.terms import load_spec_terms
    from shared.fipa_codec import AgentIdentifier, Communicate, Performative

    path = agent_spec()
    content = msgspec.msgpack.encode({"type": "moved", "name": "jar", "distance_m": 0.2})
    rec = TrafficRecord(
        seq=0, t=1.0, size=1, channel="C9", sender="a_kw", receivers=("a_km",), performative="request"
    )
    comm = Communicate(
        performative=Performative.REQUEST,
        sender=AgentIdentifier("a_kw"),
        receiver=(AgentIdentifier("a_km"),),
        content=content,
        language="L_WM",
    )
    monkeypatch.setenv("ROCO_SPEC", str(path))
    load_spec_terms.cache_clear()
    notes: list[str] = []
    try:
        (message,) = _decode_all([rec], {rec.ref: comm}, 0.0, notes)
    finally:
        load_spec_terms.cache_clear()
    assert notes == [] and type(message.content).__name__ == "Moved"
