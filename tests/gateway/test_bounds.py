"""The gateway's limits and policies as functions: numbers by their digits, JSON by its depth,
payload encodings by an allow-list (services/gateway/bounds.py); where answers may go
(services/gateway/addresses.py); which peer a foreign name is bound to
(services/gateway/identity.py)."""

from __future__ import annotations

import asyncio
import json

import pytest
from hypothesis import given
from hypothesis import strategies as st

from services.gateway.addresses import Destinations, endpoint_of
from services.gateway.bounds import BoundError, Limits, decode_payload, json_too_deep, read_digits
from services.gateway.identity import Identities, IdentityError
from services.gateway.poster import GuardedResolver


# ------------------------------------------------------------------------------- bounds
def test_numbers_are_read_by_their_digits_first() -> None:
    assert read_digits(" 0042 ", "n", 12) == 42
    for text, why in (
        ("9" * 5000, "5000 digits"),
        ("12a", "not a number"),
        ("-1", "not a number"),
        ("", "not"),
    ):
        with pytest.raises(BoundError, match=why):
            read_digits(text, "n", 12)


def _depth(value: object) -> int:
    if isinstance(value, list):
        return 1 + max((_depth(v) for v in value), default=0)
    if isinstance(value, dict):
        return 1 + max((_depth(v) for v in value.values()), default=0)
    return 0


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.text(alphabet='ab"\\[]{}', max_size=6),
    lambda inner: (
        st.lists(inner, max_size=3)
        | st.dictionaries(st.text(alphabet='k"\\[{', max_size=3), inner, max_size=3)
    ),
    max_leaves=30,
)


@given(json_values, st.integers(min_value=0, max_value=8))
def test_json_depth_is_the_nesting_of_arrays_and_objects(value: object, limit: int) -> None:
    data = json.dumps(value).encode()
    assert json_too_deep(data, limit) == (_depth(value) > limit)


def test_payload_encodings_outside_the_allow_list_are_refused() -> None:
    assert decode_payload(b"(x)", None) == b"(x)" and decode_payload(b"(x)", "UTF-8") == b"(x)"
    assert decode_payload("(café)".encode("latin-1"), "ISO-8859-1") == "(café)"
    assert decode_payload("(x)".encode("utf-16"), "utf-16") == "(x)"
    for name in ("punycode", "idna", "utf-7", "rot13", "zlib", "base64", "x-no-such"):
        with pytest.raises(BoundError, match="is not read here"):
            decode_payload(b"(x)", name)
    with pytest.raises(BoundError, match="not utf-16 text"):
        decode_payload(b"\x00\xd8a", "utf-16")


# ------------------------------------------------------------------------------- addresses
def test_roco_own_endpoints_are_not_answer_addresses() -> None:
    machine = frozenset({"localhost", "robot", "10.0.0.5"})
    dest = Destinations([("0.0.0.0", 7778), ("robot.lan", 7778), ("127.0.0.1", 7447)], Limits(), machine)
    own = [
        "http://127.0.0.1:7778/acc",
        "http://127.0.0.2:7778/x",
        "http://LOCALHOST:7778/acc",
        "http://[::1]:7778/acc",
        "http://[::ffff:127.0.0.1]:7778/acc",
        "http://robot:7778/acc",
        "http://10.0.0.5:7778/acc",
        "http://robot.lan:7778/other",
        "http://localhost:7447/",
    ]
    others = ["http://127.0.0.1:7779/acc", "http://jade.example:7778/acc", "http://10.0.0.6:7778/acc"]
    usable = dest.usable([*own, *others, "https://h:1/acc", "tcp/127.0.0.1:1", "http://h:notaport/"])
    assert usable.addresses == tuple(others)
    assert usable.skipped == {"roco_address": len(own), "not_http": 3}
    capped = dest.usable([f"http://h{i}:1/acc" for i in range(10)] + ["http://h:1/" + "a" * 3000])
    assert len(capped.addresses) == 4 and capped.skipped == {"over_cap": 7}
    assert endpoint_of("tcp/127.0.0.1:7447") == ("127.0.0.1", 7447) and endpoint_of("http://h/") == ("h", 80)


def test_a_name_that_resolves_to_roco_is_not_connected_to() -> None:
    async def resolve(port: int) -> int:
        guard = GuardedResolver(Destinations([("127.0.0.1", 7778)], Limits(), frozenset({"localhost"})))
        try:
            return len(await guard.resolve("localhost", port))
        finally:
            await guard.close()

    with pytest.raises(OSError, match="only to roco's own endpoints"):
        asyncio.run(resolve(7778))
    assert asyncio.run(resolve(7779)) >= 1


# ------------------------------------------------------------------------------- identity
class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


def test_a_name_is_bound_to_its_first_peer_while_its_conversations_last() -> None:
    clock = Clock()
    ids = Identities(Limits(linger_s=60.0, conversation_s=3600.0), clock=clock)
    a = ("http://a:1/acc",)
    ids.claim("x@p", "10.0.0.1", a, "c1")
    ids.claim("x@p", "10.0.0.1", (), "c2")  # no addresses given: the bound ones still hold
    for peer, addresses in (("10.0.0.2", a), ("10.0.0.1", ("http://b:1/acc",))):
        with pytest.raises(IdentityError, match="in use by another peer") as info:
            ids.claim("x@p", peer, addresses, "c3")
        assert info.value.reason == "identity"
    assert ids.addresses("x@p") == a
    ids.answered("x@p", "c1", final=True)
    ids.answered("x@p", "c2", final=False)  # an agree: still open
    clock.t = 1000.0
    with pytest.raises(IdentityError):
        ids.claim("x@p", "10.0.0.2", ("http://b:1/acc",), "c3")
    ids.answered("x@p", "c2", final=True)
    clock.t = 1061.0  # the last conversation ended over linger_s ago
    ids.claim("x@p", "10.0.0.2", ("http://b:1/acc",), "c3")
    assert ids.addresses("x@p") == ("http://b:1/acc",)


def test_unanswered_conversations_end_by_age_and_by_number() -> None:
    clock = Clock()
    ids = Identities(Limits(linger_s=0.0, conversation_s=100.0, max_conversations=3), clock=clock)
    for i in range(10):
        ids.claim("x@p", "10.0.0.1", ("http://a:1/acc",), f"c{i}")
    for i in range(7, 9):
        ids.answered("x@p", f"c{i}", final=True)
    clock.t = 1.0
    with pytest.raises(IdentityError, match="in use by another peer"):  # c9 is still open
        ids.claim("x@p", "10.0.0.2", ("http://b:1/acc",), "d")
    ids.answered("x@p", "c9", final=True)  # by number: the three kept were the newest, c7 to c9
    clock.t = 2.0
    ids.claim("x@p", "10.0.0.2", ("http://b:1/acc",), "d")  # x's conversations all ended: x is free
    assert ids.addresses("x@p") == ("http://b:1/acc",) and ids.bound() == 1
    clock.t = 101.0  # d unanswered for conversation_s: still open
    with pytest.raises(IdentityError, match="in use by another peer"):
        ids.claim("x@p", "10.0.0.3", ("http://c:1/acc",), "e")
    clock.t = 200.0  # d unanswered past conversation_s: ended by age
    ids.claim("x@p", "10.0.0.3", ("http://c:1/acc",), "e")
    assert ids.addresses("x@p") == ("http://c:1/acc",) and ids.bound() == 1


def test_names_beyond_the_cap_are_busy_and_platforms_are_pinned() -> None:
    ids = Identities(Limits(max_names=2), platforms={"host:1099/JADE": ("http://jade:7778/acc",)})
    ids.claim("a@p", "1.1.1.1", (), None)
    ids.claim("b@p", "1.1.1.1", (), None)
    with pytest.raises(IdentityError) as info:
        ids.claim("c@p", "1.1.1.1", (), None)
    assert info.value.reason == "busy"
    ids.claim("da0@host:1099/JADE", "2.2.2.2", ("http://jade:7778/acc",), "c")  # not counted
    ids.claim("da1@host:1099/JADE", "3.3.3.3", (), "c")
    assert ids.addresses("da1@host:1099/JADE") == ("http://jade:7778/acc",)
    with pytest.raises(IdentityError, match="configured"):
        ids.claim("da0@host:1099/JADE", "2.2.2.2", ("http://evil:1/acc",), "c")
