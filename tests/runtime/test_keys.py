"""Zenoh key expressions carry FIPA agent names as key chunks, reversibly (services.runtime.keys)."""

from __future__ import annotations

import pytest
import zenoh

from services.runtime import keys

JADE = "da0@robolab:1099/JADE"


def test_roco_agents_keep_their_short_names() -> None:
    assert keys.fipa_key("C4", "a_pl", "a_km") == "roco/fipa/C4/a_pl/a_km"
    assert keys.inbox_key("a_km") == "roco/fipa/*/*/a_km"
    assert keys.alive_key("a_co") == "roco/alive/a_co"
    assert keys.state_key("ag_ex") == "roco/state/ag_ex"
    assert keys.counters_key("a_ta") == "roco/counters/report/a_ta"


def test_a_jade_name_travels_as_one_chunk_and_back() -> None:
    key = keys.fipa_key("C2", JADE, "a_hi")
    assert key == "roco/fipa/C2/da0@robolab:1099%2FJADE/a_hi"
    assert str(zenoh.KeyExpr(key)) == key
    assert zenoh.KeyExpr(keys.inbox_key("a_hi")).intersects(zenoh.KeyExpr(key))
    assert keys.parse_fipa_key(key) == keys.FipaKey("C2", JADE, "a_hi")
    reply = keys.fipa_key("C2", "a_hi", JADE)
    assert zenoh.KeyExpr(keys.inbox_key(JADE)).intersects(zenoh.KeyExpr(reply))
    assert not zenoh.KeyExpr(keys.inbox_key(JADE)).intersects(zenoh.KeyExpr(key))
    assert keys.alive_agent(keys.alive_key(JADE)) == JADE


@pytest.mark.parametrize("name", ["a b", "9x", "", "(x)"])
def test_a_name_without_chunk_is_a_clear_error(name: str) -> None:
    for build in (
        lambda: keys.fipa_key("C1", name, "a_co"),
        lambda: keys.fipa_key("C1", "a_co", name),
        lambda: keys.inbox_key(name),
        lambda: keys.alive_key(name),
    ):
        with pytest.raises(ValueError, match="invalid agent name"):
            build()


@pytest.mark.parametrize(
    "key", ["roco/fipa/C1/a_co", "roco/fipa/C1/a%2fb/a_co", "roco/fipa/C1/a_co/9x", "x/fipa/C1/a/b"]
)
def test_keys_that_carry_no_names_are_refused(key: str) -> None:
    with pytest.raises(ValueError):
        keys.parse_fipa_key(key)


def test_alive_agent() -> None:
    assert keys.alive_agent("roco/alive/a_km") == "a_km"
    assert keys.alive_agent("roco/alive/9x") is None
    assert keys.alive_agent("roco/state/a_km") is None
