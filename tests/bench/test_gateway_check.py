"""Part 9 of ``roco bench`` (services/bench/gateway.py) checks its legitimate traffic before the
attacks (services/bench/gateway_check.py): a load whose requests the gateway refuses, or a
router whose access control drops the gateway's puts, fails the part with one line and no
figure; a sound set-up passes."""

from __future__ import annotations

import json
from collections import Counter

import pytest

from services.bench import gateway
from services.bench.gateway_check import check_legitimate
from services.bench.setup_check import SetupRefused
from services.fleet.launcher import Fleet


class _Heard:
    """A Receptor's stand-in: the conversations that reached a_hi."""

    receiver = "a_hi"
    undecodable = 0

    def __init__(self, *conversations: str) -> None:
        self.conversations = Counter(conversations)

    def wait_for(self, conversations: list[str], timeout: float) -> set[str]:
        return set(conversations) - self.conversations.keys()


FINE = {"received": 2, "forwarded": 2, "http.200": 2}


def test_the_check_passes_what_was_answered_forwarded_and_delivered() -> None:
    check_legitimate({200: 2}, FINE, ["c0-0", "c0-1"], _Heard("c0-0", "c0-1"))  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("statuses", "counters", "heard", "said"),
    [
        ({200: 1, 503: 1}, FINE, ("c0-0", "c0-1"), r"1 of 2 requests answered 200 \(200: 1, 503: 1\)"),
        ({200: 1, 0: 1}, FINE, ("c0-0", "c0-1"), r"\(none: 1, 200: 1\)"),
        (
            {200: 2},
            {**FINE, "forwarded": 1, "refused": 1, "refused.content": 1},
            ("c0-0",),
            r"forwarded 1 of 2; the gateway counted refused 1, refused.content 1; 1 of 2 never reached "
            r"a_hi \(e.g. c0-1\)$",
        ),
        ({200: 2}, FINE, ("c0-0", "c0-0", "c0-1"), r"1 reached a_hi more than once \(e.g. c0-0\)"),
        ({200: 2}, {}, ("c0-0", "c0-1"), r"no counters from the gateway$"),
    ],
)
def test_the_check_fails_what_was_not(
    statuses: dict[int, int], counters: dict[str, int], heard: tuple[str, ...], said: str
) -> None:
    with pytest.raises(SetupRefused, match=r"^the gateway's load and burst: .*" + said):
        check_legitimate(statuses, counters, ["c0-0", "c0-1"], _Heard(*heard))  # type: ignore[arg-type]


def test_the_gateway_part_fails_a_load_the_gateway_refuses() -> None:
    not_a_sentence = json.dumps({"type": "sentence", "words": 3})
    with pytest.raises(SetupRefused, match=r"^the gateway's load and burst: .*refused\.content 54"):
        gateway.measure(quick=True, load_peers=2, content=not_a_sentence)


def test_the_gateway_part_fails_when_the_router_drops_the_gateways_puts(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    start_router = Fleet.start_router

    def without_gateway_puts(self: Fleet, timeout: float = 10.0) -> None:
        assert self.security is not None
        path = self.security / "acl.json"
        acl = json.loads(path.read_text())
        (puts,) = [r for r in acl["rules"] if r["id"] == "gateway/ingress/put"]
        puts["key_exprs"] = [k for k in puts["key_exprs"] if not k.endswith("/a_hi")]
        path.write_text(json.dumps(acl))
        start_router(self, timeout)

    monkeypatch.setattr(Fleet, "start_router", without_gateway_puts)
    with pytest.raises(
        SetupRefused, match=r"^the gateway's load and burst: 54 of 54 never reached a_hi \(e.g. c0-0\)$"
    ):
        gateway.measure(quick=True, load_peers=2)


def test_the_gateway_part_passes_its_legitimate_traffic() -> None:
    figures = gateway.measure(quick=True, load_peers=2)
    assert figures.load.accepted == 4 and figures.burst.answered == 50
