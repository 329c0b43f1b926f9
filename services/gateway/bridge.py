"""The ACL gateway: roco's Zenoh channels ↔ the FIPA HTTP message transport (SC00084, SC00085
envelope, SC00070 string form). The manual: docs/gateway.md.

Every ``local@platform`` name that is no agent of roco plays the specification's external role
(``x_fipa``, ``SystemSpec.role_of``) on C8 to a_hi. On Zenoh the gateway speaks *as* that
agent (``roco/fipa/C8/da0@host:1099%2FJADE/a_hi``, the name's key chunk: shared/fipa_codec/
names.py), authenticated as ``gateway``, whom the router lets put only on
``roco/fipa/C8/$*@$*/a_hi`` and hear only ``roco/fipa/C8/a_hi/$*@$*`` (services/security/). It
holds ``roco/alive/gateway`` and answers ``roco/counters/ask`` as agents do.

In, per receiver of the envelope: a foreign sender, a receiver its role has a channel to
(else ``refuse``, SC00037 §3.17), a performative, protocol, language and content (the JSON of
the term, ``{"type": "sentence", …}``, within ``max_content`` octets and ``max_json_depth``)
the role may send there, in a conversation whose protocol state allows it (else
``not-understood``, SC00037 §3.12); re-encoded in msgpack and put. HTTP answers before that:
406 (services/gateway/bounds.py), 403 (``sender``, ``identity``: services/gateway/identity.py),
503 (``max_pending``, ``busy``). Out: an agent's communicate to a foreign name, checked against
x_fipa's interface and its conversation's protocol state, content as JSON, the roco agent
written with the gateway's address, posted (services/gateway/poster.py) to at most
``max_answer_addresses`` addresses bound to the name, never roco's own
(services/gateway/addresses.py). Every conversation bridged is followed through its protocol's
state machine (services/gateway/conversations.py: FIPA SC00026–SC00036, SC00061), which also
says when a foreign name's conversation is over. A ``refuse``, ``failure`` or
``not-understood`` is never answered. Each refusal is logged (WARNING, one line) and counted
(:data:`REFUSE_REASONS`); so is each communicate an agent said out of its conversation's
protocol (``dropped.out_of_protocol``), which is not posted.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import Counter
from collections.abc import Iterable
from typing import Any

import msgspec

from services.gateway.addresses import Destinations
from services.gateway.bounds import DEFAULT_LIMITS, BoundError, Limits, decode_payload, json_too_deep
from services.gateway.conversations import Conversations
from services.gateway.envelope import STRING_REPRESENTATION, Envelope
from services.gateway.http_mtp import MTPError, MTPMessage
from services.gateway.identity import Identities, IdentityError
from services.gateway.loop_thread import LoopThread
from services.gateway.poster import AsyncPost, Poster, PostJob
from services.gateway.server import MTPServer, Refused
from services.runtime import keys
from services.runtime.log_format import escape_controls
from services.runtime.transport import Transport
from services.spec.model import MessageKind, SystemSpec, channel_between, interface, is_foreign
from shared.fipa_codec import (
    AgentIdentifier,
    Communicate,
    DecodeError,
    EncodeError,
    Performative,
    decode,
    encode,
)
from shared.fipa_codec.batch import unpack
from shared.fipa_codec.languages import LANGUAGES, ContentError, decode_content, encode_content, load_all
from shared.fipa_codec.string_form import StringFormError, format_datetime, parse, to_bytes

__all__ = ["GATEWAY", "REFUSE_REASONS", "Gateway", "Refusal", "open_gateway", "summary"]

GATEWAY = "gateway"
"""The gateway's identity on Zenoh (services/spec_check/acl.py: GATEWAY)."""
REFUSE_REASONS: dict[str, str] = {
    "sender": "the sender is missing, or not an agent of another platform (local@platform)",
    "identity": "the foreign name is bound to another peer (services/gateway/identity.py)",
    "busy": "too many foreign names bound at once",
    "receiver": "the sender's role has no channel to the receiver in the specification",
    "not_in_interface": "performative or protocol outside the sender's role on that channel",
    "language": "no content language, or one the channel does not give that performative",
    "content": "the content is not the JSON of a term the channel allows",
    "protocol_state": "not allowed where its conversation stands in its interaction protocol",
}
"""Why the gateway refuses a message, each counted as ``refused.<reason>``."""
_REFUSE_AS = {"receiver": Performative.REFUSE}
"""Reasons answered ``refuse``; the others ``not-understood``."""
_NOT_ANSWERED = frozenset({Performative.NOT_UNDERSTOOD, Performative.REFUSE, Performative.FAILURE})
"""Performatives whose refusal is not answered: answers to answers could loop."""

log = logging.getLogger(GATEWAY)


class Refusal(Exception):
    """A message the gateway will not put on Zenoh: ``reason`` (a key of
    :data:`REFUSE_REASONS`) and ``text`` for the foreign agent: one line (control characters
    escaped, services/runtime/log_format.py), at most 500 characters."""

    def __init__(self, reason: str, text: str) -> None:
        text = escape_controls(text[:500])
        super().__init__(text)
        self.reason = reason
        self.text = text


def _language(msg: Communicate, kind: MessageKind) -> Any:
    """The content language of ``msg`` (:data:`LANGUAGES`); Refusal when ``kind`` does not
    allow it, it is unknown or ``msg``'s ontology is not its."""
    if msg.language is None or (kind.languages and msg.language not in kind.languages):
        allowed = "/".join(kind.languages) or "none"
        raise Refusal("language", f"language {msg.language} is not accepted here (only {allowed})")
    language = LANGUAGES.get(msg.language)
    if language is None:
        raise Refusal("language", f"unknown content language {msg.language}")
    if msg.ontology is not None and msg.ontology != language.ontology:
        raise Refusal("language", f"language {msg.language} needs ontology {language.ontology}")
    return language


def _outward_content(msg: Communicate) -> tuple[bytes, str | None]:
    """The content and encoding of ``msg`` as it goes out: a term as JSON, text as it is (the
    string form carries text as it is). Raises ContentError."""
    if msg.language is not None and msg.content:
        return msgspec.json.encode(decode_content(msg.language, msg.content)), None
    return msg.content, None if msg.encoding == "utf-8" else msg.encoding


class Gateway:
    """The bridge between one Zenoh ``transport`` (authenticated as :data:`GATEWAY`) and the
    HTTP transport, reachable at ``address`` (the URL foreign platforms post to). Messages from
    the HTTP server and communicates from Zenoh are handled in order on the gateway's own
    thread (:meth:`start`); answers are posted by a :class:`~services.gateway.poster.Poster`
    on ``loop`` (a new one of its own when None), to the addresses ``destinations`` allows
    (default: not ``address``). ``post`` replaces the HTTP client (tests); ``platforms``
    binds platforms to answer addresses (services/gateway/identity.py)."""

    def __init__(
        self,
        transport: Transport,
        spec: SystemSpec,
        address: str,
        *,
        limits: Limits = DEFAULT_LIMITS,
        destinations: Destinations | None = None,
        platforms: dict[str, tuple[str, ...]] | None = None,
        loop: LoopThread | None = None,
        post: AsyncPost | None = None,
    ) -> None:
        load_all()
        self.transport = transport
        self.spec = spec
        self.address = address
        self.limits = limits
        self.counters: Counter[str] = Counter()
        self.destinations = destinations or Destinations.of(address, limits=limits)
        self.identities = Identities(limits, platforms)
        self.conversations = Conversations(
            spec, max_open=limits.max_followed, max_ended=limits.max_followed_ended
        )
        """Every conversation bridged, followed through its protocol (the gateway's thread)."""
        self._own_loop = loop is None
        self.loop = loop or LoopThread("gateway-post")
        self.poster = Poster(self.loop, self.count, limits=limits, destinations=self.destinations, post=post)
        self._queue: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._pending = 0
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self.routes = [
            (ch.name, end, other)
            for ch in spec.channels
            for end, other in (ch.ends, ch.ends[::-1])
            if end in _roles(spec) and other not in spec.external_names
        ]
        """(channel, external role, agent) for every channel a foreign agent may use."""

    # ---- the threads' side ----------------------------------------------------------------
    def deliver(self, message: MTPMessage, peer: str = "") -> None:
        """Take a message the HTTP server read from ``peer`` (an IP address; any thread).
        Raises MTPError (answered 406) when its payload is not an ACL message in the string
        form within the limits, :class:`~services.gateway.server.Refused` (403) when its sender
        is no foreign name or one bound to another peer, (503) when too many messages wait or
        too many names are bound; everything else is decided on the gateway's thread."""
        envelope, limits = message.envelope, self.limits
        if envelope.acl_representation.lower() != STRING_REPRESENTATION:
            raise MTPError(
                f"acl-representation {envelope.acl_representation[:60]!r}: only {STRING_REPRESENTATION}"
            )
        if len(envelope.receivers) > limits.max_receivers:
            raise MTPError(f"{len(envelope.receivers)} receivers (at most {limits.max_receivers})")
        try:
            payload = decode_payload(message.payload, envelope.payload_encoding)
            msg = parse(payload, max_size=limits.max_body, max_tokens=limits.max_tokens)
        except BoundError as exc:
            raise MTPError(str(exc)) from None
        except StringFormError as exc:
            raise MTPError(f"the payload is no FIPA ACL message: {exc}") from None
        self.count("received")
        refusal = _sender_refusal(msg, self.spec)
        if refusal is not None:
            self._count_refusal(msg, "?", refusal)
            raise Refused(403, refusal.text)
        assert msg.sender is not None
        with self._lock:
            if self._pending >= limits.max_pending:
                raise Refused(503, f"{self._pending} messages waiting (at most {limits.max_pending})")
            self._pending += 1
        try:
            self.identities.claim(
                msg.sender.name, peer, _answer_addresses(msg, envelope), msg.conversation_id
            )
        except IdentityError as exc:
            with self._lock:
                self._pending -= 1
            self._count_refusal(msg, "?", Refusal(exc.reason, exc.text))
            raise Refused(503 if exc.reason == "busy" else 403, exc.text) from None
        self._queue.put(("in", (envelope, msg)))

    def count(self, name: str, n: int = 1) -> None:
        """Count ``name`` (any thread)."""
        with self._lock:
            self.counters[name] += n

    def _on_zenoh(self, key: str, payload: bytes) -> None:
        for communicate in unpack(payload):  # a batch: each of its communicates, in order
            self._queue.put((key, communicate))  # Zenoh thread: enqueue only

    def _on_ask(self, key: str, payload: bytes) -> None:
        self._queue.put(("ask", None))

    # ---- life ----------------------------------------------------------------------------
    def bind(self) -> None:
        """Subscribe to what agents say to foreign names, to the counters' request; hold the
        liveliness token ``roco/alive/gateway``."""
        for channel, _role, agent in self.routes:
            hears = f"{keys.FIPA_PREFIX}{channel}/{keys.key_chunk(agent)}/{keys.FOREIGN}"
            self.transport.subscribe(hears, self._on_zenoh)
        self.transport.subscribe(keys.COUNTERS_ASK, self._on_ask)
        self.transport.announce(keys.alive_key(GATEWAY))

    def start(self) -> None:
        """Handle what arrives on a thread of its own until :meth:`stop`."""
        self._thread = threading.Thread(target=self._run, name="gateway", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the gateway's thread, then the posting (answers not yet posted are dropped)."""
        self._queue.put(("stop", None))
        if self._thread is not None:
            self._thread.join(timeout=10.0)
        self.poster.close()
        if self._own_loop:
            self.loop.stop()

    def _run(self) -> None:
        while True:
            kind, item = self._queue.get()
            if kind == "stop":
                return
            try:
                if kind == "in":
                    with self._lock:
                        self._pending -= 1
                    self._inbound(*item)
                elif kind == "ask":
                    self._report_counters()
                else:
                    self._outbound(kind, item)
            except Exception:  # nothing one message does stops the gateway
                self.count("internal_errors")
                log.exception("handling %s raised", kind)

    def _report_counters(self) -> None:
        with self._lock:
            counters = dict(self.counters)
        session = getattr(self.transport, "session_id", "")
        report = {"agent": GATEWAY, "time": time.time(), "session": session, "counters": counters}
        self.transport.publish(keys.counters_key(GATEWAY), msgspec.json.encode(report))

    # ---- in: HTTP → Zenoh ----------------------------------------------------------------
    def _inbound(self, envelope: Envelope, msg: Communicate) -> None:
        for receiver in envelope.receivers:
            try:
                channel, communicate = self._admit(msg, receiver.name)
            except Refusal as refusal:
                self._refuse(msg, receiver.name, refusal)
                continue
            assert communicate.sender is not None
            key = keys.fipa_key(channel, communicate.sender.name, receiver.name)
            try:
                payload = encode(communicate)
            except EncodeError as exc:  # larger than any communicate may be
                self._refuse(msg, receiver.name, Refusal("content", str(exc)))
                continue
            why = self.conversations.follow(communicate.sender.name, receiver.name, communicate, inbound=True)
            if why is not None:  # last: only what is put on Zenoh is followed
                self._refuse(msg, receiver.name, Refusal("protocol_state", why))
                continue
            self.transport.publish(key, payload)
            self.count("forwarded")
            if self._ended(communicate.sender.name, receiver.name, msg):  # e.g. roco-notify's inform
                self.identities.ended(communicate.sender.name, msg.conversation_id)
            log.info(
                "%s → %s on %s: %s (conversation %s)",
                communicate.sender.name,
                receiver.name,
                channel,
                msg.performative.value,
                msg.conversation_id,
            )

    def _admit(self, msg: Communicate, receiver: str) -> tuple[str, Communicate]:
        """The channel and the communicate to put on Zenoh for ``receiver``, or Refusal. The
        sender is a foreign name (checked by :meth:`deliver`)."""
        assert msg.sender is not None
        sender = msg.sender.name
        role = self.spec.role_of(sender)
        channel = channel_between(self.spec, role, receiver) if receiver != role else None
        if channel is None:
            raise Refusal("receiver", f"{sender} may not address {receiver} (no channel of {role} to it)")
        kind = _kind(interface(self.spec, role).sends, receiver, msg)
        if kind is None:
            raise Refusal(
                "not_in_interface",
                f"{msg.performative.value} in protocol {msg.protocol} is not allowed from {role} to "
                f"{receiver} on {channel.name}",
            )
        content, language, ontology, encoding = b"", msg.language, msg.ontology, msg.encoding
        if msg.content:
            content, language, ontology = self._term(msg, kind)
            encoding = "msgpack"
        communicate = msgspec.structs.replace(
            msg,
            receiver=(AgentIdentifier(receiver),),
            content=content,
            language=language,
            ontology=ontology,
            encoding=encoding,
        )
        return channel.name, communicate

    def _check_size(self, content: bytes) -> None:
        """Refusal when the JSON ``content`` is over ``max_content`` octets or nested deeper than
        ``max_json_depth``."""
        limits = self.limits
        if len(content) > limits.max_content:
            raise Refusal("content", f"the content is {len(content)} octets (at most {limits.max_content})")
        if json_too_deep(content, limits.max_json_depth):
            raise Refusal("content", f"the content nests deeper than {limits.max_json_depth} levels")

    def _term(self, msg: Communicate, kind: MessageKind) -> tuple[bytes, str, str]:
        """The content of ``msg`` (JSON of a term) in its language's encoding, its language
        and ontology; Refusal when they are not what ``kind`` allows, or the JSON is over
        ``max_content`` octets or nested deeper than ``max_json_depth``."""
        language = _language(msg, kind)
        self._check_size(msg.content)
        union: Any = language.types[0]
        for t in language.types[1:]:
            union = union | t
        try:
            term = msgspec.json.decode(msg.content, type=union)
        except (msgspec.DecodeError, msgspec.ValidationError, RecursionError) as exc:
            raise Refusal("content", f"the content is not a {msg.language} term in JSON: {exc}") from None
        if kind.contents and type(term).__name__ not in kind.contents:
            raise Refusal("content", f"{msg.performative.value} here carries {', '.join(kind.contents)}")
        name, data = encode_content(term)
        return data, name, language.ontology

    def _count_refusal(self, msg: Communicate, receiver: str, refusal: Refusal) -> None:
        self.count("refused")
        self.count(f"refused.{refusal.reason}")
        sender = msg.sender.name if msg.sender is not None else "?"
        log.warning(
            "refused %s from %s to %s: %s",
            msg.performative.value,
            sender[:300],
            receiver[:300],
            refusal.text[:300],
        )

    def _ended(self, foreign: str, agent: str, msg: Communicate) -> bool:
        """Whether ``msg``'s conversation between ``foreign`` and ``agent`` is over."""
        return self.conversations.ended(foreign, agent, msg.protocol, msg.conversation_id)

    def _refuse(self, msg: Communicate, receiver: str, refusal: Refusal) -> None:
        """Count and log ``refusal`` of ``msg`` for ``receiver``, and answer it in the sender's
        conversation as the receiver: ``refuse`` (FIPA SC00037 §3.17) or ``not-understood``
        (§3.12), the reason as content; never a refuse, failure or not-understood. The answer
        is not followed in the conversation: it answers a message that never entered it, and
        the roco agent's own answers in it still pass."""
        self._count_refusal(msg, receiver, refusal)
        if msg.sender is None:
            return  # nobody to answer
        ended = self._ended(msg.sender.name, receiver, msg)  # e.g. a refused opening: none began
        if msg.performative in _NOT_ANSWERED:
            if ended:
                self.identities.ended(msg.sender.name, msg.conversation_id)
            return  # never answer an answer (no loops)
        try:
            me = AgentIdentifier(receiver, (self.address,))
        except ValueError:  # the receiver's name is no agent name: answer as the gateway
            me = AgentIdentifier(f"{GATEWAY}@roco", (self.address,))
        answer = Communicate(
            performative=_REFUSE_AS.get(refusal.reason, Performative.NOT_UNDERSTOOD),
            sender=me,
            receiver=(msg.sender,),
            content=refusal.text.encode(),
            protocol=msg.protocol,
            conversation_id=msg.conversation_id,
            in_reply_to=msg.reply_with,
        )
        self._send_out(answer, msg.sender.name, ended)

    # ---- out: Zenoh → HTTP ---------------------------------------------------------------
    def _receives(self, channel: str, sender: str, receiver: str, msg: Communicate) -> bool:
        """Whether the external role of ``receiver`` receives ``msg`` from ``sender`` on
        ``channel`` (its interface in the specification)."""
        role = self.spec.role_of(receiver)
        if role not in self.spec.external_names:
            return False
        return any(
            k.channel == channel
            and k.sender == sender
            and k.performative == msg.performative.value
            and k.protocol == msg.protocol
            for k in interface(self.spec, role).receives
        )

    def _outbound(self, key: str, payload: bytes) -> None:
        try:
            channel, sender, receiver = keys.parse_fipa_key(key)
            msg = decode(payload)
        except (ValueError, DecodeError) as exc:
            self.count("dropped.malformed")
            log.warning("dropped what came on %s: %s", key, exc)
            return
        if not self._receives(channel, sender, receiver, msg):
            self.count("dropped.not_in_interface")
            log.warning(
                "dropped %s from %s to %s on %s: outside the specification",
                msg.performative.value,
                sender,
                receiver,
                channel,
            )
            return
        try:
            content, encoding = _outward_content(msg)
        except ContentError as exc:
            self.count("dropped.content")
            log.warning("dropped %s from %s: %s", msg.performative.value, sender, exc)
            return
        why = self.conversations.follow(receiver, sender, msg, inbound=False)
        if why is not None:  # last: only what is posted is followed
            self.count("dropped.out_of_protocol")
            log.warning(
                "dropped %s from %s to %s (conversation %s): %s",
                msg.performative.value,
                sender,
                receiver[:300],
                (msg.conversation_id or "")[:300],
                why[:300],
            )
            return
        answer = msgspec.structs.replace(
            msg,
            sender=AgentIdentifier(sender, (self.address,)),
            receiver=(AgentIdentifier(receiver, self.identities.addresses(receiver)),),
            content=content,
            encoding=encoding,
        )
        self.count("answered")  # taken to be posted (a failed post is counted post_failed)
        self._send_out(answer, receiver, self._ended(receiver, sender, msg))

    def _send_out(self, msg: Communicate, foreign: str, ended: bool) -> None:
        """Post ``msg`` to the foreign agent ``foreign`` at the addresses bound to its name
        that may be posted to (services/gateway/addresses.py), in order, until one takes it;
        ``ended``: its conversation is over (the name's binding no longer holds it open)."""
        self.identities.answered(foreign, msg.conversation_id, final=ended)
        given = self.identities.addresses(foreign)
        usable = self.destinations.usable(given)
        for reason, n in usable.skipped.items():
            self.count(f"post_skipped.{reason}", n)
        if not usable.addresses:
            self.count("post_failed")
            why = "it gave no address" if not given else "none of its addresses may be posted to"
            log.warning("nowhere to post %s to %s: %s", msg.performative.value, foreign[:300], why)
            return
        payload = to_bytes(msg)
        assert msg.sender is not None
        envelope = Envelope(
            to=(AgentIdentifier(foreign, given),),
            from_=msg.sender,
            payload_encoding="US-ASCII" if payload.isascii() else "UTF-8",
            date=format_datetime(time.time()),
        )
        what = f"{msg.performative.value} from {msg.sender.name} to {foreign[:300]}"
        self.poster.submit(PostJob(foreign, usable.addresses, MTPMessage(envelope, payload), what))


def _answer_addresses(msg: Communicate, envelope: Envelope) -> tuple[str, ...]:
    """Where the sender of ``msg`` wants answers: its reply-to's addresses, else its own, else
    the envelope's ``from``'s; () when none gives any."""
    candidates: Iterable[AgentIdentifier] = (*msg.reply_to, *((msg.sender,) if msg.sender else ()))
    if envelope.from_ is not None:
        candidates = (*candidates, envelope.from_)
    return next((a.addresses for a in candidates if a.addresses), ())


def _sender_refusal(msg: Communicate, spec: SystemSpec) -> Refusal | None:
    """The refusal of a message whose sender is missing or no foreign name, else None."""
    sender = msg.sender.name if msg.sender is not None else ""
    if sender and is_foreign(sender) and spec.role_of(sender) in _roles(spec):
        return None
    return Refusal(
        "sender",
        f"{sender[:300] or 'no sender'}: only agents of other platforms (local@platform) come in here",
    )


def _roles(spec: SystemSpec) -> tuple[str, ...]:
    """The external roles the gateway speaks for: those of no platform of their own (``x_fipa``;
    ``…@ros2`` names play x_ros2, served by ``roco ros2``)."""
    return tuple(e.name for e in spec.externals if not e.platform)


def _kind(sends: tuple[MessageKind, ...], receiver: str, msg: Communicate) -> MessageKind | None:
    for k in sends:
        if k.receiver == receiver and k.performative == msg.performative.value and k.protocol == msg.protocol:
            return k
    return None


def open_gateway(
    transport: Transport,
    spec: SystemSpec,
    host: str,
    port: int,
    address: str,
    *,
    routers: Iterable[str] = (),
    limits: Limits = DEFAULT_LIMITS,
    platforms: dict[str, tuple[str, ...]] | None = None,
) -> tuple[Gateway, MTPServer]:
    """A :class:`Gateway` on ``transport`` for ``spec``, subscribed and forwarding, and its FIPA
    HTTP message transport (SC00084) serving on ``host:port``, foreign platforms told to post
    to ``address``; answers are never posted to ``address``, ``host:port`` or the fleet's
    ``routers`` (Zenoh endpoints). Stop both with ``server.stop()`` then ``gateway.stop()``.
    Raises OSError when the port cannot be bound (then nothing was started)."""
    destinations = Destinations.of(address, (host, port), routers, limits)
    gateway = Gateway(transport, spec, address, limits=limits, destinations=destinations, platforms=platforms)
    server = MTPServer((host, port), gateway.deliver, gateway.count, limits=limits, loop=gateway.loop)
    try:
        server.start()
    except OSError:
        gateway.stop()
        raise
    gateway.bind()
    gateway.start()
    return gateway, server


def summary(counters: dict[str, int]) -> str:
    """The gateway's counters in one line (``roco status``): what came in, what was refused
    and why (FIPA refusals by reason, HTTP refusals by status), what went out::

        received 3, forwarded 2, refused 1 (receiver 1), http refused 2 (406 1, 413 1),
        answered 3, posted 2, post_failed 1, post_skipped 1 (roco_address 1)

    A part that is 0 is left out, but for received, forwarded, refused and answered; so is
    ``dropped N (…)`` (what a_hi said that the specification does not let out, or that its
    conversation's protocol state does not allow: ``out_of_protocol``) and
    ``internal_errors``."""

    def group(prefix: str) -> dict[str, int]:
        return {k[len(prefix) :]: v for k, v in counters.items() if k.startswith(prefix) and v}

    def detail(parts: dict[str, int]) -> str:
        return " (" + ", ".join(f"{k} {v}" for k, v in sorted(parts.items())) + ")" if parts else ""

    refused = group("refused.")
    http = {k: v for k, v in group("http.").items() if k != "200"}
    dropped = group("dropped.")
    skipped = group("post_skipped.")
    line = [
        f"received {counters.get('received', 0)}",
        f"forwarded {counters.get('forwarded', 0)}",
        f"refused {counters.get('refused', 0)}{detail(refused)}",
    ]
    if http:
        line.append(f"http refused {sum(http.values())}{detail(http)}")
    line.append(f"answered {counters.get('answered', 0)}")
    for name in ("posted", "post_failed", "post_dropped"):
        if counters.get(name):
            line.append(f"{name} {counters[name]}")
    if skipped:
        line.append(f"post_skipped {sum(skipped.values())}{detail(skipped)}")
    if dropped:
        line.append(f"dropped {sum(dropped.values())}{detail(dropped)}")
    if counters.get("internal_errors"):
        line.append(f"internal_errors {counters['internal_errors']}")
    return ", ".join(line)
