"""A system declares its own content languages in its specification (``[languages.NAME]``,
services/spec/terms.py ``register_languages``): their terms come from modules the
specification names, shared by any number of agents and languages; loading the specification
registers them in every process (the recorder's live monitor included); what cannot be
registered is refused in one line naming the language, and nothing is half-registered."""

from __future__ import annotations

import itertools
import textwrap
from collections.abc import Callable, Iterator
from pathlib import Path

import msgspec
import pytest

from services.spec.model import SpecError, load
from shared.fipa_codec.languages import ContentError, decode_content, encode_content, load_all
from tests.support.codec_registry import languages_restored

_ids = itertools.count()

TERMS = """
import msgspec


class Order(msgspec.Struct, frozen=True, tag="order", kw_only=True):
    item: str
    bin: int = 0


class Sorted(msgspec.Struct, frozen=True, tag="sorted", kw_only=True):
    item: str
    bin: int


class Jam(msgspec.Struct, frozen=True, tag="jam", kw_only=True):
    where_m: float


class Stock(msgspec.Struct, frozen=True, tag="cell_stock", kw_only=True):
    bins: int


TERMS = (Order, Sorted, Jam, Stock)
"""

BELT_LANGUAGES = ", ".join(f'{p} = "L_BELT"' for p in ("request", "agree", "inform", "failure", "refuse"))

SPEC = """
system = "Cell"

[[requirements]]
id = "R"
text = "sort the ordered items"

[[requirements]]
id = "R1"
parent = "R"
text = "take orders"

[[requirements]]
id = "R2"
parent = "R"
text = "move the belt"

[[steps]]
number = 1
requirements = ["R", "R1"]
split = "Cell"
into = ["op", "sc"]
tasks = {{ op = "takes orders", sc = "sorts" }}
new_channels = [{{ number = 1, ends = ["op", "sc"], transmits = "orders" }}]

[[steps]]
number = 2
requirements = ["R2"]
split = "sc"
into = ["so", "cv"]
tasks = {{ so = "sorts", cv = "moves the belt" }}
reallocated = [{{ number = 1, from = "sc", to = "so" }}]
new_channels = [{{ number = 2, ends = ["so", "cv"], transmits = "the belt's state" }}]

[[agents]]
name = "a_op"
group = "op"
implementation = "{package}.agents:Operator"
terms = "{package}.terms"

[[agents]]
name = "a_so"
group = "so"
implementation = "{package}.agents:Sorter"
terms = "{package}.terms"

[[agents]]
name = "a_cv"
group = "cv"
implementation = "{package}.agents:Conveyor"

[protocols.fipa-request]

[languages.L_ORD]
ontology = "O_Cell"
terms = ["{package}.terms:Order", "{package}.terms:Sorted"]
description = "orders for the cell and their outcome"
{extra}
[[channels]]
name = "C1"
ends = ["a_op", "a_so"]
transmits = "orders and their outcome"
  [[channels.protocols]]
  protocol = "fipa-request"
  initiator = "a_op"
  languages = {{ request = "L_ORD", agree = "L_ORD", inform = "L_ORD", failure = "L_ORD", refuse = "L_ORD" }}
  contents = {{ request = ["Order"], inform = ["Sorted"] }}

[[channels]]
name = "C2"
ends = ["a_so", "a_cv"]
transmits = "the belt's state"
  [[channels.protocols]]
  protocol = "fipa-request"
  initiator = "a_so"
  languages = {{ {belt} }}
"""

BELT = """
[languages.L_BELT]
ontology = "O_Cell"
terms = ["{package}.terms:Jam"]
"""


@pytest.fixture(autouse=True)
def registry_restored() -> Iterator[None]:
    """The codec's registry as it was before the test (a test's languages leave with it)."""
    with languages_restored():
        yield


Spec = Callable[..., Path]


@pytest.fixture
def cell_spec(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Spec:
    """Writes a package with ``terms.py`` under ``tmp_path`` and a specification of three
    agents whose two channels speak the languages L_ORD and L_BELT; returns its path."""
    monkeypatch.syspath_prepend(str(tmp_path))

    def write(extra: str = BELT, terms: str = TERMS) -> Path:
        package = f"cell_{next(_ids)}"
        (tmp_path / package).mkdir()
        (tmp_path / package / "__init__.py").write_text("")
        (tmp_path / package / "terms.py").write_text(textwrap.dedent(terms))
        path = tmp_path / f"{package}.toml"
        path.write_text(
            SPEC.format(package=package, extra=extra.format(package=package), belt=BELT_LANGUAGES)
        )
        return path

    return write


def _term(language: str, name: str) -> type[msgspec.Struct]:
    return next(t for t in load_all()[language].types if t.__name__ == name)


def test_a_declared_language_decodes_its_terms_and_nothing_else(cell_spec: Spec) -> None:
    spec = load(cell_spec())
    assert set(spec.languages) == {"L_ORD", "L_BELT"}
    assert load_all()["L_ORD"].ontology == "O_Cell"
    order = _term("L_ORD", "Order")(item="bolt", bin=2)
    language, data = encode_content(order)
    assert language == "L_ORD" and decode_content("L_ORD", data) == order
    jam = _term("L_BELT", "Jam")(where_m=0.4)
    assert encode_content(jam)[0] == "L_BELT"
    with pytest.raises(ContentError):  # Order is L_ORD's, not L_BELT's
        decode_content("L_BELT", data)


def test_two_agents_naming_one_terms_module_share_it_and_loading_twice_registers_once(
    cell_spec: Spec,
) -> None:
    path = cell_spec()
    load(path)
    before = {name: lang.types for name, lang in load_all().items()}
    load(path)
    assert {name: lang.types for name, lang in load_all().items()} == before
    # Stock, in no [languages] table, joins the one language of the agents' channels (L_ORD)
    assert [t.__name__ for t in before["L_ORD"]] == ["Order", "Sorted", "Stock"]
    assert [t.__name__ for t in before["L_BELT"]] == ["Jam"]


def test_spec_check_accepts_a_system_with_its_own_languages(cell_spec: Spec) -> None:
    from services.spec.check import check_report

    ok, text = check_report(cell_spec())
    assert ok, text


def test_a_roco_language_is_extended_by_a_declaration_without_an_ontology(cell_spec: Spec) -> None:
    load(cell_spec(BELT + '\n[languages.L_WM]\nterms = ["{package}.terms:Stock"]\n'))
    assert "Stock" in {t.__name__ for t in load_all()["L_WM"].types}


def test_one_term_in_two_languages_is_refused(cell_spec: Spec) -> None:
    with pytest.raises(SpecError, match=r"language L_WM: .*Jam already belongs to L_BELT"):
        load(cell_spec(BELT + '\n[languages.L_WM]\nterms = ["{package}.terms:Jam"]\n'))


def _table(name: str, *lines: str) -> str:
    return f"\n[languages.{name}]\n" + "".join(f"{line}\n" for line in lines)


CELL = 'ontology = "O_Cell"'


@pytest.mark.parametrize(
    ("extra", "why"),
    [
        (_table("L_BELT", 'terms = ["{package}.terms:Jam"]'), "L_BELT: a new language needs an ontology"),
        (_table("L_BELT", CELL), "L_BELT: a new language needs an ontology and at least one term"),
        (_table("L_WM", 'ontology = "O_Other"'), "L_WM: ontology 'O_Other', but it is 'O_RoCo'"),
        (_table("L_BELT", CELL, 'terms = ["{package}.terms:Gone"]'), "lists no term 'Gone'"),
        (_table("L_BELT", CELL, 'terms = ["no_such.terms"]'), "'no_such.terms' cannot be imported"),
        (_table("L_BELT", CELL, 'terms = ["{package}.terms:Order"]'), "Order already belongs to L_ORD"),
        (_table('"L BELT"', CELL, 'terms = ["{package}.terms:Jam"]'), "a language's name is one word"),
        (_table("L_BELT", CELL, 'terms = ["{package}.terms:Jam"]', "size = 3"), "unknown field"),
    ],
    ids=[
        "no ontology",
        "no terms",
        "other ontology",
        "no such term",
        "no module",
        "term taken",
        "two words",
        "unknown field",
    ],
)
def test_a_language_that_cannot_be_registered_is_refused_in_one_line(
    cell_spec: Spec, extra: str, why: str
) -> None:
    before = {name: lang.types for name, lang in load_all().items() if name != "L_ORD"}
    with pytest.raises(SpecError) as caught:
        load(cell_spec(extra))
    assert why in str(caught.value) and "\n" not in str(caught.value), caught.value
    assert {name: lang.types for name, lang in load_all().items() if name != "L_ORD"} == before


def test_the_recorder_s_live_monitor_loads_the_languages_of_the_specification(cell_spec: Spec) -> None:
    """The recorder decodes the system's content for its live monitor: loading the monitor
    registers the specification's languages (services/spec_live/sink.py ``watched``)."""
    from services.spec_live.sink import watched

    path = cell_spec()
    assert "L_BELT" not in load_all()
    watched(path)
    assert "L_BELT" in load_all()


@pytest.mark.parametrize(
    ("edit", "why"),
    [
        (('name = "a_cv"\n', 'name = "a_cv"\nrole = "pilot"\n'), "agent a_cv: unknown role 'pilot'"),
        (
            (
                'name = "a_cv"\n',
                'name = "a_cv"\nrole = "person"\n',
                'name = "a_op"\n',
                'name = "a_op"\nrole = "person"\n',
            ),
            "role 'person' is played by a_op and a_cv: one agent at most",
        ),
        (('name = "a_cv"\n', 'name = "a_so"\n'), "an agent is named twice"),
    ],
    ids=["unknown role", "two persons", "one name twice"],
)
def test_roles_are_known_and_played_once(cell_spec: Spec, edit: tuple[str, ...], why: str) -> None:
    """What roco grants an agent beyond its channels follows a role (services/spec/model.py
    ``ROLES``), which one agent at most plays."""
    path = cell_spec()
    text = path.read_text()
    for old, new in zip(edit[::2], edit[1::2], strict=True):
        text = text.replace(old, new, 1)
    path.write_text(text)
    with pytest.raises(SpecError) as caught:
        load(path)
    assert why in str(caught.value), caught.value


def test_the_agent_playing_a_role_is_found_by_it(cell_spec: Spec) -> None:
    path = cell_spec()
    path.write_text(path.read_text().replace('name = "a_op"\n', 'name = "a_op"\nrole = "person"\n', 1))
    spec = load(path)
    assert (spec.playing("person"), spec.playing("robot")) == ("a_op", None)
