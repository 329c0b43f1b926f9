"""Zenoh key expressions of roco: a key names channel, sender and receiver, so that the router's
access control can say who may send what where (docs/security.md, "Who may send what where").

``roco/fipa/<channel>/<sender>/<receiver>``  one communicate (msgpack :class:`Communicate`)
``roco/alive/<agent>``                       liveliness token of a running agent (white pages)
``roco/human/in`` / ``roco/human/out``       a_hi's receptor and effector: text from/to a person
``roco/state/<agent>``                       state snapshots (executor, for viewers)
``roco/state/<agent>/camera``                head-camera images (ag_ex, while someone subscribes)
``roco/sim/disturb``                         the simulated world's disturbances (a person moves an
                                             object): JSON :class:`services.agents.executor.agent.Disturbance`
``roco/counters/ask``                        any put here makes every agent publish its counters
``roco/counters/report/<agent>``             an agent's counters (JSON, ``Engine.counters_report``)
``roco/recorder/flags``                      a query here: the traffic recorder answers with the
                                             live requirement flags of its run (JSON,
                                             services/recorder/flags.py ``FlagsReply``)
``roco/human/outcomes``                      a query here: a_hi answers with the final reports it
                                             gave last (JSON list of ``HumanReport``)

``<sender>``, ``<receiver>`` and ``<agent>`` are FIPA agent names written as the key chunk
``shared.fipa_codec.names.key_chunk`` maps them to: roco's agents (``a_co``) as themselves,
JADE's ``da0@host:1099/JADE`` as ``da0@host:1099%2FJADE``; :func:`parse_fipa_key` maps them back.
A name that is no FIPA word has no chunk: ValueError.
"""

from __future__ import annotations

from typing import NamedTuple

from shared.fipa_codec.names import key_chunk, name_of_key_chunk

PREFIX = "roco"
FIPA_PREFIX = f"{PREFIX}/fipa/"
"""What every communicate's key starts with."""
FIPA_ALL = f"{FIPA_PREFIX}**"
FIPA_CACHES = f"{PREFIX}/fipa/**/@adv/**"
"""What zenoh-ext's advanced publishers of communicates declare below their key (cache
queryable, liveliness token, heartbeat: ``<key>/@adv/pub/<zid>/<eid>/_``) and what the recorder's
advanced subscriber asks; ``**`` never matches a ``@`` chunk, so ``FIPA_ALL`` does not cover it."""
ALIVE_ALL = f"{PREFIX}/alive/*"
HUMAN_IN = f"{PREFIX}/human/in"
HUMAN_OUT = f"{PREFIX}/human/out"
HUMAN_OUT_CACHES = f"{HUMAN_OUT}/@adv/**"
"""What a_hi's advanced publisher of reports declares below ``HUMAN_OUT`` (cache queryable,
liveliness token, heartbeat) and what the person's tools' advanced subscribers ask and watch
(services/runtime/reports.py)."""
HUMAN_OUTCOMES = f"{PREFIX}/human/outcomes"
"""a_hi's queryable of the final reports it gave last, kept across its restarts
(services/runtime/person.py): what a person's tool asks when its wait for an
outcome runs long (services/runtime/reports.py ``ask_outcomes``)."""
SIM_DISTURB = f"{PREFIX}/sim/disturb"
SIM_CLOCK = f"{PREFIX}/sim/clock"
"""ag_ex publishes the simulation's time here at its state rate; the agents' clocks follow it
while the fleet runs as fast as possible (services/runtime/clock.py)."""
RECORDER_SYNC = f"{PREFIX}/recorder/sync"
"""A token put here reaches the traffic recorder after every communicate routed before it;
the recorder writes them all, then puts the token on ``RECORDER_SYNCED``."""
RECORDER_SYNCED = f"{PREFIX}/recorder/synced"
RECORDER_FLAGS = f"{PREFIX}/recorder/flags"
"""The traffic recorder's queryable: a query here (``roco status``) is answered with the
requirement properties the live monitor flagged violated in the recorder's run folder."""
COUNTERS_ASK = f"{PREFIX}/counters/ask"
"""A put here (any payload) asks every agent for its counters (``roco status``)."""
COUNTERS_ALL = f"{PREFIX}/counters/report/*"
FOREIGN = "$*@$*"
"""A key-expression chunk matching the key chunk of every agent name ``local@platform`` (an
agent of another platform, services/spec/model.py ``is_foreign``) and of none of roco's own
agents: ``roco/fipa/C8/$*@$*/a_hi`` is any foreign agent's communicate to a_hi on C8."""


class FipaKey(NamedTuple):
    channel: str
    sender: str
    receiver: str


def fipa_key(channel: str, sender: str, receiver: str) -> str:
    """The key one communicate from ``sender`` to ``receiver`` (agent names) on ``channel`` is
    put on. Raises ValueError when a name is no agent name (see the module docstring)."""
    return f"{PREFIX}/fipa/{channel}/{key_chunk(sender)}/{key_chunk(receiver)}"


def caches_of(key: str) -> str:
    """The key expression of what advanced publishers on communicate ``key`` declare below it."""
    return f"{key}/@adv/**"


def is_cached_key(key: str) -> bool:
    """Whether puts on ``key`` go through an advanced publisher with a cache
    (services/runtime/transport.py): communicates, and a_hi's reports to the person."""
    return key.startswith(FIPA_PREFIX) or key == HUMAN_OUT


def is_communicate_key(key: str) -> bool:
    """Whether ``key`` carries communicates (``roco/fipa/…``), one or a batch of them
    (shared/fipa_codec/batch.py)."""
    return key.startswith(FIPA_PREFIX)


def inbox_key(agent: str) -> str:
    """The key expression an agent subscribes to: every channel, every sender, to it."""
    return f"{PREFIX}/fipa/*/*/{key_chunk(agent)}"


def parse_fipa_key(key: str) -> FipaKey:
    """Split a communicate key into channel and the agent names of sender and receiver;
    raises ValueError when it is not ``roco/fipa/C/S/R`` with S and R key chunks of names."""
    parts = key.split("/")
    if len(parts) != 5 or parts[0] != PREFIX or parts[1] != "fipa":
        raise ValueError(f"not a communicate key: {key!r}")
    return FipaKey(parts[2], name_of_key_chunk(parts[3]), name_of_key_chunk(parts[4]))


def alive_key(agent: str) -> str:
    """The liveliness token key of ``agent``."""
    return f"{PREFIX}/alive/{key_chunk(agent)}"


def alive_agent(key: str) -> str | None:
    """The agent name a liveliness token key (:func:`alive_key`) carries; None when ``key`` is
    not ``roco/alive/<chunk>`` with the key chunk of an agent name."""
    prefix = f"{PREFIX}/alive/"
    if not key.startswith(prefix):
        return None
    try:
        return name_of_key_chunk(key[len(prefix) :])
    except ValueError:
        return None


def state_key(agent: str) -> str:
    return f"{PREFIX}/state/{key_chunk(agent)}"


def camera_key(agent: str) -> str:
    """Where ``agent`` (ag_ex) puts its head camera's images (msgpack
    velma/executor/camera_feed.py ``CameraFrame``), rendered only while a subscriber matches
    (Zenoh's matching status): ``roco ros2 --camera`` (docs/ros2.md)."""
    return f"{PREFIX}/state/{key_chunk(agent)}/camera"


def counters_key(agent: str) -> str:
    """Where ``agent`` publishes its counters when asked on :data:`COUNTERS_ASK`."""
    return f"{PREFIX}/counters/report/{key_chunk(agent)}"
