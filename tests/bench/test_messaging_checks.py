"""Part 2 checks its own setup (services/bench/messaging.py): the roco pair's exchange is the
work timed, and a pair the access control refuses fails the part instead of giving a figure."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import msgspec
import pytest
import zenoh

from services.bench import messaging
from services.bench.messaging import (
    Latency,
    MessagingFigures,
    MessagingSummary,
    PairFigures,
    SetupError,
    Throughput,
    check_exchange,
    pair_exchange,
)
from services.bench.synthetic import matched
from services.deploy import deploy
from services.runtime import keys
from services.security.folder import ACL_FILE


def _good_counters() -> tuple[dict[str, int], dict[str, int]]:
    """An initiator's and a participant's counter deltas after one round of 300 round trips
    (and 50 warm-up ones) and two streams of 5,000 informs."""
    ini = {"sent.request": 350, "sent.subscribe": 2, "received.inform": 10_350, "received.agree": 2}
    par = {"received.request": 350, "received.subscribe": 2, "sent.inform": 10_350, "sent.agree": 2}
    return ini, par


def test_the_exchange_check_passes_the_work_asked_for() -> None:
    ini, par = _good_counters()
    check_exchange({**ini, "published": 9}, par, pair_exchange(1, 300, 5000))


@pytest.mark.parametrize(
    ("plant", "says"),
    [
        (lambda i, p: p.update({"received.request": 349}), "b_ini0 sent 350 request and b_par0 received 349"),
        (
            lambda i, p: i.update({"received.inform": 10_349}),
            "b_par0 sent 10350 inform and b_ini0 received 10349",
        ),
        (lambda i, p: (i.update({"sent.request": 351}), p.update({"received.request": 351})), "not 350"),
        (lambda i, p: i.update({"received.not-understood": 1}), "b_ini0: received.not-understood 1"),
        (lambda i, p: p.update({"sent.refuse": 1}), "b_par0: sent.refuse 1"),
        (
            lambda i, p: p.update({"rejected": 1, "rejected.content": 1}),
            "b_par0: rejected 1, rejected.content 1",
        ),
    ],
)
def test_the_exchange_check_catches_a_dropped_refused_or_rejected_communicate(plant: Any, says: str) -> None:
    ini, par = _good_counters()
    plant(ini, par)
    with pytest.raises(SetupError, match=says):
        check_exchange(ini, par, pair_exchange(1, 300, 5000))


def test_a_pair_the_access_control_refuses_fails_the_part(monkeypatch: pytest.MonkeyPatch) -> None:
    real = deploy.prepare
    refused = keys.fipa_key("B0", "b_ini0", "b_par0")

    def refusing(out: Path, spec: Any, *, tls: bool, days: int = 365) -> list[str]:
        """The credentials as issued, with an ACL that grants no put of b_ini0's requests."""
        names = real(out, spec, tls=tls, days=days)
        acl = json.loads((out / ACL_FILE).read_text())
        for rule in acl["rules"]:
            rule["key_exprs"] = [k for k in rule["key_exprs"] if k != refused]
        (out / ACL_FILE).write_text(json.dumps(acl))
        return names

    monkeypatch.setattr(deploy, "prepare", refusing)
    monkeypatch.setattr(messaging, "REACH_TIMEOUT_S", 3.0)
    with pytest.raises(
        SetupError,
        match=r"route was not there: b_ini0: no answer within 3 s: requests sent 1 \(retransmitted \d+ "
        r"times\), received by b_par0 0",
    ):
        messaging.messaging(1, 10, 100)


def test_the_summary_takes_each_headline_figure_from_its_testbed() -> None:
    def pair(rt_us: float, stream: int) -> PairFigures:
        return PairFigures(
            roco_rt=Latency([rt_us * 1e-6] * 3),
            raw_rt=Latency([(rt_us - 10) * 1e-6] * 3),
            raw_poll_rt=Latency([(rt_us - 20) * 1e-6] * 3),
            poll_us=500.0,
            roco_tput=Throughput([(stream + 3, 1000, 1.0, 1)]),
            roco_tput_single=Throughput([(stream + 1, 1000, 1.0, 1)]),
            raw_tput=Throughput([(stream + 5, 1000, 1.0, 1)]),
        )

    s = MessagingFigures(pair(300, 10_000), pair(200, 20_000), {}, 200, "peer").summary
    assert (s.round_trip_p50_us, s.raw_polling_p50_us, s.raw_sleeping_p50_us) == pytest.approx(
        (300, 280, 290)
    )
    assert (s.round_trip_open_p50_us, s.raw_polling_open_p50_us) == pytest.approx((200, 180))
    assert (s.stream_per_s, s.stream_batched_per_s, s.raw_stream_per_s) == (10_000, 10_002, 10_004)
    assert s.stream_open_per_s == 20_000 and s.round_trip_ratio == pytest.approx(300 / 280)
    assert msgspec.json.decode(msgspec.json.encode(s), type=MessagingSummary) == s


def test_a_bare_publisher_is_matched_only_once_a_subscriber_is_there() -> None:
    conf = zenoh.Config()
    conf.insert_json5("scouting/multicast/enabled", "false")
    conf.insert_json5("listen/endpoints", "[]")
    session = zenoh.open(conf)
    try:
        publisher = session.declare_publisher("roco/bench/test/matched")
        assert not matched(publisher, 0.2)
        session.declare_subscriber("roco/bench/test/matched", lambda _sample: None)
        assert matched(publisher, 10.0)
    finally:
        session.close()


def test_a_pair_whose_participant_never_comes_fails_the_testbed_s_start() -> None:
    bed = messaging.Testbed(1, reach_s=2.0)
    try:
        with pytest.raises(
            SetupError, match=r"route was not there: b_ini0: no answer within 2 s: requests sent 0 "
        ):
            bed.start(["b_ini0"], [])
    finally:
        bed.stop()
