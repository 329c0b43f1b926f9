"""The ACL gateway: roco's Zenoh channels ↔ the FIPA HTTP message transport.

How a foreign agent fits the specification
    The specification has an external role (``[[externals]]``, ``x_fipa``) substituting a group
    outside the system that a decomposition step declares (step 8), and a channel (C8) between
    it and a_hi: every agent named ``local@platform`` that is not an agent of roco (JADE's
    ``da0@host:1099/JADE``) plays that role (``SystemSpec.role_of``). So a foreign agent may
    open fipa-request with a_hi, in L_HC, carrying a ``Sentence`` — what a person may say — and
    nothing else; a_hi's runtime checks it like any communicate, as x_fipa's.

How the gateway appears on Zenoh
    As the foreign agents themselves: a request from ``da0@host:1099/JADE`` to a_hi is put on
    ``roco/fipa/C8/da0@host:1099%2FJADE/a_hi`` (the name's key chunk, shared/fipa_codec/names.py)
    with that sender, so the recorder, ``roco sniff`` and a_hi see the JADE-named agent. The
    gateway's session authenticates as the identity ``gateway`` (services/security/), which the
    router's access control allows to put only on the keys of channels whose one end is an
    external role, from any foreign name to the agent at the other end
    (``roco/fipa/C8/$*@$*/a_hi``: a chunk holding ``@``, as foreign names do and roco's do not),
    and to hear only that agent's communicates to foreign names (``roco/fipa/C8/a_hi/$*@$*``):
    whatever the gateway does, the router keeps it to C8. It holds
    the liveliness token ``roco/alive/gateway`` and answers ``roco/counters/ask`` on
    ``roco/counters/report/gateway`` as agents do (``roco status`` shows the counters).

What crosses, checked against the specification (per receiver of the envelope)
    In: the ACL payload (FIPA SC00070 string form, in the envelope's ``payload-encoding``) must
    name a foreign sender; the receiver must
    be an agent the sender's role has a channel to; the performative and protocol must be ones
    the role may send there; the content must be the JSON of a term of a language the
    specification gives that performative (``{"type": "sentence", "text": "…"}``: msgspec's JSON
    of the L_HC term, its tag in ``type``), of a type the channel allows. The gateway re-encodes
    it in the language (msgpack) and puts it on Zenoh. Out: a communicate of an agent to a
    foreign name is checked against the role's interface, its content written as the JSON of
    its term (a plain-text reason as it is), and posted to the addresses the foreign agent gave:
    its ``:reply-to``'s, else its ``:sender``'s, else the envelope's ``from``'s. The gateway
    writes the roco agent as ``(agent-identifier :name a_hi :addresses (sequence <gateway
    address>))`` so that the foreign platform sends its next message back through the gateway.

What is refused
    A message the checks above reject is answered at once, posted back to the sender's address
    in its conversation (conversation-id, in-reply-to = its reply-with, protocol), from the agent
    it addressed: ``refuse`` when the sender may not address that agent or is no foreign agent
    (FIPA SC00037 §3.17: the action will not be done), ``not-understood`` when it may address
    it but not with that performative, protocol, language or content (SC00037 §3.12); the
    reason is the content, as text. Each refusal is logged (WARNING, one line naming sender,
    receiver and reason) and counted: ``refused`` and ``refused.<reason>``
    (:data:`REFUSE_REASONS`). Answers that cannot be posted are counted ``post_failed``.
"""

from __future__ import annotations

import logging
import queue
import threading
import time
from collections import Counter, OrderedDict
from collections.abc import Callable
from typing import Any

import msgspec

from services.gateway.envelope import STRING_REPRESENTATION, Envelope
from services.gateway.http_mtp import MTPError, MTPMessage, MTPServer, post_message
from services.runtime import keys
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
KNOWN_AGENTS = 1024
"""Foreign agents whose addresses the gateway remembers (the oldest is forgotten first)."""
REFUSE_REASONS: dict[str, str] = {
    "sender": "the sender is missing, or not an agent of another platform (local@platform)",
    "receiver": "the sender's role has no channel to the receiver in the specification",
    "not_in_interface": "performative or protocol outside the sender's role on that channel",
    "language": "no content language, or one the channel does not give that performative",
    "content": "the content is not the JSON of a term the channel allows",
}
"""Why the gateway refuses a message, each counted as ``refused.<reason>``."""
_UTF8 = frozenset({"", "utf-8", "utf8", "us-ascii", "ascii"})
"""Payload encodings read as UTF-8 octets (US-ASCII is a subset); others are decoded first."""
_REFUSE_AS = {"sender": Performative.REFUSE, "receiver": Performative.REFUSE}
"""Reasons answered ``refuse``; the others ``not-understood``."""

log = logging.getLogger(GATEWAY)
Post = Callable[[str, MTPMessage, float], None]
"""How a message is posted to a foreign platform: (address, message, timeout s); raises MTPError
or OSError when it is not taken (``services.gateway.http_mtp.post_message``)."""


class Refusal(Exception):
    """A message the gateway will not put on Zenoh: ``reason`` (a key of
    :data:`REFUSE_REASONS`) and ``text`` for the foreign agent."""

    def __init__(self, reason: str, text: str) -> None:
        super().__init__(text)
        self.reason = reason
        self.text = text


class Gateway:
    """The bridge between one Zenoh ``transport`` (authenticated as :data:`GATEWAY`) and the
    HTTP transport, reachable at ``address`` (the URL foreign platforms post to). Messages from
    the HTTP server and communicates from Zenoh are handled in order on the gateway's own
    thread (:meth:`start`); ``post`` sends a message to a foreign platform (for tests)."""

    def __init__(
        self,
        transport: Transport,
        spec: SystemSpec,
        address: str,
        *,
        post: Post = post_message,
        post_timeout: float = 10.0,
    ) -> None:
        load_all()
        self.transport = transport
        self.spec = spec
        self.address = address
        self.counters: Counter[str] = Counter()
        self._post = post
        self._post_timeout = post_timeout
        self._known: OrderedDict[str, AgentIdentifier] = OrderedDict()
        self._queue: queue.SimpleQueue[tuple[str, Any]] = queue.SimpleQueue()
        self._thread: threading.Thread | None = None
        self._lock = threading.Lock()
        self.routes = [
            (ch.name, end, other)
            for ch in spec.channels
            for end, other in (ch.ends, ch.ends[::-1])
            if end in spec.external_names and other not in spec.external_names
        ]
        """(channel, external role, agent) for every channel a foreign agent may use."""

    # ---- the threads' side: enqueue only ------------------------------------------------
    def deliver(self, message: MTPMessage) -> None:
        """Take a message the HTTP server read (any thread). Raises MTPError (answered 406)
        when its payload is not an ACL message in the string form; everything else is decided
        on the gateway's thread."""
        if message.envelope.acl_representation.lower() != STRING_REPRESENTATION:
            raise MTPError(
                f"acl-representation {message.envelope.acl_representation!r}: only {STRING_REPRESENTATION}"
            )
        charset = (message.envelope.payload_encoding or "").strip().lower()
        payload: str | bytes = message.payload
        if charset not in _UTF8:  # another character set the envelope names (ISO-8859-1…)
            try:
                payload = message.payload.decode(charset)
            except (LookupError, UnicodeDecodeError) as exc:
                raise MTPError(f"the payload is not {charset} text: {exc}") from None
        try:
            msg = parse(payload)
        except StringFormError as exc:
            raise MTPError(f"the payload is no FIPA ACL message: {exc}") from None
        self._queue.put(("in", (message.envelope, msg)))

    def count(self, name: str) -> None:
        """Count ``name`` (any thread)."""
        with self._lock:
            self.counters[name] += 1

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
        self._queue.put(("stop", None))
        if self._thread is not None:
            self._thread.join(timeout=10.0)

    def _run(self) -> None:
        while True:
            kind, item = self._queue.get()
            if kind == "stop":
                return
            try:
                if kind == "in":
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
        self.count("received")
        if msg.sender is not None:
            self._remember(msg, envelope)
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
            self.transport.publish(key, payload)
            self.count("forwarded")
            log.info(
                "%s → %s on %s: %s (conversation %s)",
                communicate.sender.name,
                receiver.name,
                channel,
                msg.performative.value,
                msg.conversation_id,
            )

    def _admit(self, msg: Communicate, receiver: str) -> tuple[str, Communicate]:
        """The channel and the communicate to put on Zenoh for ``receiver``, or Refusal."""
        sender = msg.sender.name if msg.sender is not None else ""
        if not sender or not is_foreign(sender) or sender in self.spec.agent_names:
            raise Refusal(
                "sender",
                f"{sender or 'no sender'}: only agents of other platforms (local@platform) come in here",
            )
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

    def _term(self, msg: Communicate, kind: MessageKind) -> tuple[bytes, str, str]:
        """The content of ``msg`` (JSON of a term) in its language's encoding, its language
        and ontology; Refusal when they are not what ``kind`` allows."""
        if msg.language is None or (kind.languages and msg.language not in kind.languages):
            allowed = "/".join(kind.languages) or "none"
            raise Refusal("language", f"language {msg.language} is not accepted here (only {allowed})")
        language = LANGUAGES.get(msg.language)
        if language is None:
            raise Refusal("language", f"unknown content language {msg.language}")
        if msg.ontology is not None and msg.ontology != language.ontology:
            raise Refusal("language", f"language {msg.language} needs ontology {language.ontology}")
        union: Any = language.types[0]
        for t in language.types[1:]:
            union = union | t
        try:
            term = msgspec.json.decode(msg.content, type=union)
        except (msgspec.DecodeError, msgspec.ValidationError) as exc:
            raise Refusal("content", f"the content is not a {msg.language} term in JSON: {exc}") from None
        if kind.contents and type(term).__name__ not in kind.contents:
            raise Refusal("content", f"{msg.performative.value} here carries {', '.join(kind.contents)}")
        name, data = encode_content(term)
        return data, name, language.ontology

    def _refuse(self, msg: Communicate, receiver: str, refusal: Refusal) -> None:
        self.count("refused")
        self.count(f"refused.{refusal.reason}")
        sender = msg.sender.name if msg.sender is not None else "?"
        log.warning("refused %s from %s to %s: %s", msg.performative.value, sender, receiver, refusal.text)
        if msg.performative is Performative.NOT_UNDERSTOOD or msg.sender is None:
            return  # never answer a not-understood; nobody to answer
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
        self._send_out(answer, msg.sender.name)

    # ---- out: Zenoh → HTTP ---------------------------------------------------------------
    def _outbound(self, key: str, payload: bytes) -> None:
        try:
            channel, sender, receiver = keys.parse_fipa_key(key)
            msg = decode(payload)
        except (ValueError, DecodeError) as exc:
            self.count("dropped.malformed")
            log.warning("dropped what came on %s: %s", key, exc)
            return
        role = self.spec.role_of(receiver)
        allowed = (
            any(
                k.channel == channel
                and k.sender == sender
                and k.performative == msg.performative.value
                and k.protocol == msg.protocol
                for k in interface(self.spec, role).receives
            )
            if role in self.spec.external_names
            else False
        )
        if not allowed:
            self.count("dropped.not_in_interface")
            log.warning(
                "dropped %s from %s to %s on %s: outside the specification",
                msg.performative.value,
                sender,
                receiver,
                channel,
            )
            return
        content = msg.content
        encoding = msg.encoding
        if msg.language is not None and msg.content:
            try:
                content = msgspec.json.encode(decode_content(msg.language, msg.content))
            except ContentError as exc:
                self.count("dropped.content")
                log.warning("dropped %s from %s: %s", msg.performative.value, sender, exc)
                return
            encoding = None
        elif encoding == "utf-8":
            encoding = None  # a reason as text: the string form carries text as it is
        target = self._known.get(receiver, AgentIdentifier(receiver))
        answer = msgspec.structs.replace(
            msg,
            sender=AgentIdentifier(sender, (self.address,)),
            receiver=(target,),
            content=content,
            encoding=encoding,
        )
        self.count("answered")  # taken to be posted (a failed post is counted post_failed)
        self._send_out(answer, receiver)

    def _send_out(self, msg: Communicate, foreign: str) -> None:
        """Post ``msg`` to the foreign agent ``foreign`` at the addresses it gave, in order,
        until one takes it."""
        target = self._known.get(foreign)
        addresses = target.addresses if target is not None else ()
        if not addresses:
            self.count("post_failed")
            log.warning("nowhere to post %s to %s: it gave no address", msg.performative.value, foreign)
            return
        payload = to_bytes(msg)
        ascii_only = payload.isascii()
        assert msg.sender is not None
        envelope = Envelope(
            to=(target,) if target is not None else (),
            from_=msg.sender,
            payload_encoding="US-ASCII" if ascii_only else "UTF-8",
            date=format_datetime(time.time()),
        )
        for address in addresses:
            try:
                self._post(address, MTPMessage(envelope, payload), self._post_timeout)
            except (MTPError, OSError) as exc:
                log.warning(
                    "posting %s to %s at %s failed: %s", msg.performative.value, foreign, address, exc
                )
                continue
            log.info("%s → %s at %s: %s", msg.sender.name, foreign, address, msg.performative.value)
            return
        self.count("post_failed")

    def _remember(self, msg: Communicate, envelope: Envelope) -> None:
        """Where the sender of ``msg`` wants answers: its reply-to's addresses, else its own,
        else the envelope's ``from``."""
        assert msg.sender is not None
        name = msg.sender.name
        candidates = [*msg.reply_to, msg.sender]
        if envelope.from_ is not None:
            candidates.append(envelope.from_)
        found = next((a for a in candidates if a.addresses), msg.sender)
        self._known.pop(name, None)
        self._known[name] = AgentIdentifier(name, found.addresses)
        while len(self._known) > KNOWN_AGENTS:
            self._known.popitem(last=False)


def _kind(sends: tuple[MessageKind, ...], receiver: str, msg: Communicate) -> MessageKind | None:
    for k in sends:
        if k.receiver == receiver and k.performative == msg.performative.value and k.protocol == msg.protocol:
            return k
    return None


def open_gateway(
    transport: Transport, spec: SystemSpec, host: str, port: int, address: str
) -> tuple[Gateway, MTPServer]:
    """A :class:`Gateway` on ``transport`` for ``spec``, subscribed and forwarding, and its FIPA
    HTTP message transport (SC00084) serving on ``host:port``, foreign platforms told to post
    to ``address``. Stop both with ``server.stop()`` then ``gateway.stop()``. Raises OSError
    when the port cannot be bound (then nothing was started)."""
    gateway = Gateway(transport, spec, address)
    server = MTPServer((host, port), gateway.deliver, gateway.count)
    gateway.bind()
    gateway.start()
    server.start()
    return gateway, server


def summary(counters: dict[str, int]) -> str:
    """The gateway's counters in one line (``roco status``): ``received 3, forwarded 2,
    refused 1 (receiver 1), answered 4, post_failed 0``."""
    refused = {k.split(".", 1)[1]: v for k, v in counters.items() if k.startswith("refused.") and v}
    line = [f"received {counters.get('received', 0)}", f"forwarded {counters.get('forwarded', 0)}"]
    line.append(f"refused {counters.get('refused', 0)}")
    if refused:
        line[-1] += " (" + ", ".join(f"{k} {v}" for k, v in sorted(refused.items())) + ")"
    line += [f"answered {counters.get('answered', 0)}", f"post_failed {counters.get('post_failed', 0)}"]
    return ", ".join(line)
