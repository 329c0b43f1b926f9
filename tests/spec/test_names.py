"""services/spec/names.py, rendered from the specification (services/spec/render_names.py):
the committed module is what the shipped specification gives; each name is the
specification's spelling as a ``str`` (so roles, keys and the wire see the same strings); a
name that cannot be a Python name, or two that would be one, are refused with one line; and a
specification with a new channel gives a module that names it."""

from __future__ import annotations

import enum
from pathlib import Path

import msgspec
import pytest

from services.runtime import keys
from services.runtime.roles import (
    INITIATOR,
    PARTICIPANT,
    RoleDecl,
    handles,
    initiator,
    on_deadline,
    participant,
)
from services.spec import names
from services.spec.model import ChannelProtocol, ChannelSpec, default_spec, load
from services.spec.render_names import (
    NAMES_FILE,
    NamesError,
    bring_up_to_date,
    check,
    difference,
    python_name,
    render,
    spellings,
    typed_names,
    write,
)
from shared.fipa_codec import Performative
from tests.spec_check.walkthrough import NEXT, walkthrough_spec

SPEC = default_spec()
NEW = NEXT.channel_name
"""A channel number the shipped specification has not used yet (the walk-through's: C9)."""
NOTICE = NEXT.notice_channel_name
"""The walk-through's second new channel (to a_hi: C10)."""


def test_the_committed_names_module_is_what_the_specification_gives() -> None:
    assert NAMES_FILE.read_text() == render(SPEC)
    assert check(NAMES_FILE, SPEC, "services/spec/names.py") is None
    assert Path(names.__file__) == NAMES_FILE
    head = NAMES_FILE.read_text().split('"""')[1]
    assert "GENERATED from the specification" in head and "roco spec names" in head


def test_every_channel_protocol_and_language_of_the_specification_has_its_name() -> None:
    assert [c.value for c in names.Channel] == [ch.name for ch in SPEC.channels]
    assert [p.value for p in names.ProtocolName] == list(SPEC.protocols)
    assert [lang.value for lang in names.Language] == ["L_EX", "L_HC", "L_HFSM", "L_SD", "L_SW", "L_WM"]
    assert names.FIPA_REQUEST is names.ProtocolName.FIPA_REQUEST == "fipa-request"
    assert names.COORDINATE == "coordinate" and names.C5 is names.Channel.C5 and names.L_EX == "L_EX"
    assert spellings(SPEC) == typed_names(SPEC).aliases()
    assert spellings(SPEC)["FIPA_SUBSCRIBE"] == "fipa-subscribe"


def test_a_name_is_the_specification_s_spelling_wherever_a_string_goes() -> None:
    for member in (names.C5, names.FIPA_REQUEST, names.L_SD):
        assert isinstance(member, str) and isinstance(member, enum.StrEnum)
        assert f"{member}" == str(member) == "".join([member]) == member.value
        assert hash(member) == hash(member.value) and {member.value: 1}[member] == 1
    assert msgspec.msgpack.encode(names.FIPA_REQUEST) == msgspec.msgpack.encode("fipa-request")
    assert keys.fipa_key(names.C5, "a_ta", "ag_ex") == keys.fipa_key("C5", "a_ta", "ag_ex")


def test_a_role_keeps_the_spelling_as_a_plain_str_whichever_way_it_was_named() -> None:
    typed = participant(names.C5, names.FIPA_REQUEST, names.L_EX, names.L_SD)
    plain = participant("C5", "fipa-request", "L_EX", "L_SD")
    assert typed == plain and hash(typed) == hash(plain)
    assert {type(v) for v in (typed.channel, typed.protocol, *typed.languages)} == {str}
    assert initiator(names.C3, names.FIPA_REQUEST, names.L_HFSM, reply_by_s=1.0) == RoleDecl(
        "C3", "fipa-request", INITIATOR, ("L_HFSM",), 1.0
    )
    assert str(typed) == "participant of fipa-request on C5 (L_EX, L_SD)"


def test_a_handler_names_performatives_and_a_string_that_is_none_is_refused() -> None:
    def handler(self: object, conv: object) -> None: ...

    marked = handles(names.FIPA_REQUEST, PARTICIPANT, Performative.REQUEST, channel=names.C8)(handler)
    (key,) = marked.__roco_handles__  # type: ignore[attr-defined]
    assert (key.protocol, key.performative, key.channel) == ("fipa-request", Performative.REQUEST, "C8")
    assert type(key.protocol) is str and type(key.channel) is str

    def other(self: object, conv: object) -> None: ...

    (deadline,) = on_deadline(names.COORDINATE, PARTICIPANT)(other).__roco_handles__  # type: ignore[attr-defined]
    assert type(deadline.protocol) is str and deadline.performative is None
    slipped: str = "requets"
    with pytest.raises(ValueError, match="'requets' is not a FIPA performative"):
        handles(names.FIPA_REQUEST, PARTICIPANT, slipped)  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("kind", "value", "name"),
    [
        ("channel", "C5", "C5"),
        ("protocol", "fipa-request-when", "FIPA_REQUEST_WHEN"),
        ("language", "l_wm", "L_WM"),
    ],
)
def test_a_python_name_is_the_spelling_upper_cased_with_underscores(kind: str, value: str, name: str) -> None:
    assert python_name(kind, value) == name


@pytest.mark.parametrize("value", ["9C", "C 5", "C.5", "_C", "", "Cä"])
def test_a_spelling_that_cannot_be_a_python_name_is_refused_with_one_line(value: str) -> None:
    with pytest.raises(NamesError) as refused:
        python_name("channel", value)
    assert str(refused.value).startswith(f"channel {value!r} has no Python name in services/spec/names.py")
    assert "\n" not in str(refused.value)


def test_two_spellings_of_one_python_name_are_refused() -> None:
    clash = ChannelSpec("c1", ("a_co", "a_ta"), "a second C1", SPEC.channels[0].protocols)
    spec = msgspec.structs.replace(SPEC, channels=(*SPEC.channels, clash))
    with pytest.raises(NamesError, match="channel 'c1' and channel 'C1' would both be C1"):
        render(spec)
    as_language = ChannelProtocol("coordinate", "a_co", languages={"request": "C2"})
    mixed = ChannelSpec(NEW, ("a_co", "a_ta"), "x", (as_language,))
    spec = msgspec.structs.replace(SPEC, channels=(*SPEC.channels, mixed))
    with pytest.raises(NamesError, match="language 'C2' and channel 'C2' would both be C2"):
        render(spec)
    assert "C2" in spellings(spec)  # read leniently by the code scan: the first keeps the name


@pytest.mark.walkthrough
def test_a_new_channel_is_named_and_the_committed_module_lacks_it(tmp_path: Path) -> None:
    spec = load(walkthrough_spec(tmp_path / "spec.toml"))
    text = render(spec)
    assert f"\n{NEW} = Channel.{NEW}\n" in text
    assert f'    {NEW} = "{NEW}"\n    """Between a_wt and a_km (fipa-subscribe): ' in text
    assert difference(NAMES_FILE.read_text(), spec) == f"no name {NEW}, {NOTICE}, KITCHEN_WARNING"
    assert check(NAMES_FILE, spec, "services/spec/names.py") == (
        "services/spec/names.py differs from what the specification gives "
        f"(no name {NEW}, {NOTICE}, KITCHEN_WARNING): run `roco spec names`"
    )
    module: dict[str, object] = {}
    exec(compile(text, "names", "exec"), module)
    assert module[NEW] == NEW and module["FIPA_QUERY"] == "fipa-query"


@pytest.mark.walkthrough
def test_write_and_bring_up_to_date(tmp_path: Path) -> None:
    spec = load(walkthrough_spec(tmp_path / "spec.toml"))
    target = tmp_path / "names.py"
    assert write(target, spec) and not write(target, spec)
    assert target.read_text() == render(spec)
    root = tmp_path / "root"
    assert bring_up_to_date(root, spec) == (
        f"no names module at {root / 'services' / 'spec' / 'names.py'}: "
        "`roco spec names --file F` writes one elsewhere"
    )
    (root / "services" / "spec").mkdir(parents=True)
    (root / "services" / "spec" / "names.py").write_text(NAMES_FILE.read_text())
    assert bring_up_to_date(root, spec).startswith(f"wrote {root / 'services' / 'spec' / 'names.py'}: ")
    assert bring_up_to_date(root, spec).endswith("is up to date")
    with pytest.raises(NamesError, match="no such names module"):
        check(tmp_path / "none.py", spec)
